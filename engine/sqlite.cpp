#include "engine/sqlite.hpp"

namespace millflow::engine::sql {
namespace {

// SQLite's "database or disk is full" names neither; say which file and what to do (nothing
// committed is lost: the failed transaction rolls back).
std::string full_disk_hint(sqlite3* db) {
  if (db == nullptr || (sqlite3_errcode(db) & 0xff) != SQLITE_FULL) return "";  // any extended code
  return std::string(" (") + sqlite3_db_filename(db, "main") +
         ": free space on its disk, then run the command again; what was committed is kept)";
}

[[noreturn]] void fail(sqlite3* db, std::string_view what) {
  throw Error(std::string(what) + ": " + (db ? sqlite3_errmsg(db) : "out of memory") +
              full_disk_hint(db));
}

// A writer killed at the wrong moment (kill -9) can leave a WAL that needs recovery, or, in a first
// submit killed before the file switched to WAL, a hot rollback journal; a read-only connection can
// do neither (SQLITE_READONLY_RECOVERY, SQLITE_READONLY_ROLLBACK): a short read-write connection,
// that creates nothing and writes no page beyond undoing the dead writer's, recovers it first.
void recover_for_reading(sqlite3* reader, const std::filesystem::path& file) {
  sqlite3_extended_result_codes(reader, 1);
  const char* probe = "SELECT count(*) FROM sqlite_master";
  const int probed = sqlite3_exec(reader, probe, nullptr, nullptr, nullptr);
  if (probed != SQLITE_READONLY_RECOVERY && probed != SQLITE_READONLY_ROLLBACK) return;
  sqlite3* writer = nullptr;
  if (sqlite3_open_v2(file.c_str(), &writer, SQLITE_OPEN_READWRITE | SQLITE_OPEN_NOMUTEX,
                      nullptr) == SQLITE_OK) {
    sqlite3_busy_timeout(writer, 10000);
    sqlite3_exec(writer, probe, nullptr, nullptr, nullptr);
  }
  sqlite3_close(writer);
}

}  // namespace

Connection::Connection(const std::filesystem::path& file, Access access) {
  const int flags = access == Access::read_only ? SQLITE_OPEN_READONLY
                                                : SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE;
  if (sqlite3_open_v2(file.c_str(), &db_, flags | SQLITE_OPEN_NOMUTEX, nullptr) != SQLITE_OK) {
    const std::string message = "cannot open database " + file.string() + ": " +
                                (db_ ? sqlite3_errmsg(db_) : "out of memory");
    sqlite3_close(db_);
    throw Error(message);
  }
  sqlite3_busy_timeout(db_, 10000);
  if (access == Access::read_only) recover_for_reading(db_, file);
  exec("PRAGMA foreign_keys = ON");
  if (access == Access::read_only) exec("PRAGMA query_only = ON");
}

Connection::~Connection() {
  cached_.clear();  // finalized before the connection closes
  sqlite3_close_v2(db_);
}

void Connection::exec(std::string_view sql) {
  char* message = nullptr;
  const std::string text(sql);
  if (sqlite3_exec(db_, text.c_str(), nullptr, nullptr, &message) != SQLITE_OK) {
    const std::string error = message ? message : sqlite3_errmsg(db_);
    sqlite3_free(message);
    throw Error("SQL error: " + error + full_disk_hint(db_) + " in: " + text.substr(0, 200));
  }
}

Statement Connection::prepare(std::string_view sql) {
  return Statement(db_, sql);
}

Statement& Connection::cached(std::string_view sql) {
  auto found = cached_.find(sql);
  if (found == cached_.end()) found = cached_.emplace(std::string(sql), prepare(sql)).first;
  return found->second;
}

int Connection::user_version() {
  auto statement = prepare("PRAGMA user_version");
  statement.step();
  return static_cast<int>(statement.integer(0));
}

Statement::Statement(sqlite3* db, std::string_view sql) : db_(db) {
  const char* tail = nullptr;
  if (sqlite3_prepare_v2(db, sql.data(), static_cast<int>(sql.size()), &stmt_, &tail) !=
      SQLITE_OK) {
    fail(db, "cannot prepare \"" + std::string(sql.substr(0, 200)) + "\"");
  }
  if (stmt_ == nullptr) throw Error("empty SQL statement");
  if (tail != nullptr &&
      std::string_view(tail).find_first_not_of(" \t\r\n;") != std::string_view::npos) {
    sqlite3_finalize(stmt_);
    throw Error("only one SQL statement at a time, found more after: " +
                std::string(sql.substr(0, 200)));
  }
}

Statement::~Statement() {
  sqlite3_finalize(stmt_);
}

Statement::Statement(Statement&& other) noexcept : db_(other.db_), stmt_(other.stmt_) {
  other.stmt_ = nullptr;
}

void Statement::bind(int index, std::int64_t value) {
  sqlite3_bind_int64(stmt_, index, value);
}
void Statement::bind(int index, double value) {
  sqlite3_bind_double(stmt_, index, value);
}
void Statement::bind(int index, std::string_view value) {
  sqlite3_bind_text(stmt_, index, value.data(), static_cast<int>(value.size()), SQLITE_TRANSIENT);
}
void Statement::bind(int index, std::nullopt_t) {
  sqlite3_bind_null(stmt_, index);
}
void Statement::bind(int index, const std::optional<std::string>& value) {
  if (value)
    bind(index, *value);
  else
    bind(index, std::nullopt);
}

bool Statement::step() {
  const int code = sqlite3_step(stmt_);
  if (code == SQLITE_ROW) return true;
  if (code == SQLITE_DONE) return false;
  fail(db_, "SQL step failed for \"" + std::string(sqlite3_sql(stmt_)).substr(0, 200) + "\"");
}

void Statement::run() {
  while (step()) {
  }
  reset();
}

void Statement::reset() {
  sqlite3_reset(stmt_);
  sqlite3_clear_bindings(stmt_);
}

std::string Statement::text(int column) const {
  const auto* data = sqlite3_column_text(stmt_, column);
  if (data == nullptr) return {};
  return std::string(reinterpret_cast<const char*>(data),
                     static_cast<size_t>(sqlite3_column_bytes(stmt_, column)));
}

Transaction::Transaction(Connection& connection)
    : connection_(connection), nested_(sqlite3_get_autocommit(connection.handle()) == 0) {
  connection_.cached(nested_ ? "SAVEPOINT nested" : "BEGIN IMMEDIATE").run();
}

Transaction::~Transaction() {
  if (done_) return;
  const char* undo = nested_ ? "ROLLBACK TO nested; RELEASE nested" : "ROLLBACK";
  sqlite3_exec(connection_.handle(), undo, nullptr, nullptr, nullptr);
}

void Transaction::commit() {
  connection_.cached(nested_ ? "RELEASE nested" : "COMMIT").run();
  done_ = true;
}

}  // namespace millflow::engine::sql
