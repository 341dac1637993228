#pragma once
// A thin RAII layer over the SQLite C API: connections, prepared statements, transactions.
#include <sqlite3.h>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <unordered_map>

namespace millflow::engine::sql {

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class Access { read_only, read_write };

class Statement {
 public:
  Statement(sqlite3* db, std::string_view sql);
  ~Statement();
  Statement(Statement&& other) noexcept;
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  Statement& operator=(Statement&&) = delete;

  template <typename... Values>
  Statement& bind_all(const Values&... values) {
    reset();
    int index = 1;
    (bind(index++, values), ...);
    return *this;
  }
  void bind(int index, std::int64_t value);
  void bind(int index, int value) { bind(index, static_cast<std::int64_t>(value)); }
  void bind(int index, double value);
  void bind(int index, std::string_view value);
  void bind(int index, const std::string& value) { bind(index, std::string_view(value)); }
  void bind(int index, const char* value) { bind(index, std::string_view(value)); }
  void bind(int index, std::nullopt_t);
  void bind(int index, const std::optional<std::string>& value);

  bool step();  // true while a row is available
  void run();   // steps to completion, for statements without results
  void reset();

  int columns() const { return sqlite3_column_count(stmt_); }
  std::string column_name(int column) const { return sqlite3_column_name(stmt_, column); }
  bool is_null(int column) const { return sqlite3_column_type(stmt_, column) == SQLITE_NULL; }
  int column_type(int column) const { return sqlite3_column_type(stmt_, column); }
  std::int64_t integer(int column) const { return sqlite3_column_int64(stmt_, column); }
  double real(int column) const { return sqlite3_column_double(stmt_, column); }
  std::string text(int column) const;
  bool read_only() const { return sqlite3_stmt_readonly(stmt_) != 0; }

 private:
  sqlite3* db_;
  sqlite3_stmt* stmt_ = nullptr;
};

// Heterogeneous lookup: finding a statement by its SQL text allocates nothing.
struct SqlHash {
  using is_transparent = void;
  size_t operator()(std::string_view sql) const { return std::hash<std::string_view>{}(sql); }
};

class Connection {
 public:
  // read_write creates the file if missing. read_only also sets PRAGMA query_only.
  Connection(const std::filesystem::path& file, Access access);
  ~Connection();
  Connection(Connection&& other) noexcept : db_(other.db_), cached_(std::move(other.cached_)) {
    other.db_ = nullptr;
  }
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;
  Connection& operator=(Connection&&) = delete;

  void exec(std::string_view sql);  // runs one or more statements without results
  Statement prepare(std::string_view sql);
  // Prepared on first use and kept: statements run once per task (a commit's handful, and BEGIN,
  // SAVEPOINT, RELEASE, COMMIT) are parsed once per connection instead of each time.
  Statement& cached(std::string_view sql);
  int user_version();
  std::int64_t last_insert_rowid() const { return sqlite3_last_insert_rowid(db_); }
  sqlite3* handle() const { return db_; }

 private:
  sqlite3* db_ = nullptr;
  std::unordered_map<std::string, Statement, SqlHash, std::equal_to<>> cached_;
};

// BEGIN IMMEDIATE on construction; rolls back on destruction unless committed. Inside an open
// transaction it is a savepoint instead, so a caller can group several writes (each its own
// Transaction) into one commit, and a failed inner part still rolls back alone.
class Transaction {
 public:
  explicit Transaction(Connection& connection);
  ~Transaction();
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;
  void commit();

 private:
  Connection& connection_;
  bool nested_;
  bool done_ = false;
};

}  // namespace millflow::engine::sql
