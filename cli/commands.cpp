#include "cli/commands.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <functional>
#include <iostream>
#include <optional>

#include "cli/estimate.hpp"
#include "cli/executor_choice.hpp"
#include "cli/number_checks.hpp"
#include "engine/attempt_files.hpp"
#include "engine/coordinator_lock.hpp"
#include "engine/database_path.hpp"
#include "engine/inspect.hpp"
#include "engine/interrupt.hpp"
#include "engine/outputs.hpp"
#include "engine/slurm_executor.hpp"
#include "engine/validation.hpp"
#include "util/durable_file.hpp"

namespace millflow::cli {
namespace {

namespace fs = std::filesystem;
using engine::TableFormat;

constexpr int kBusy = 3;

// Writes an --out directory through util::fill_directory_durably (a kill while `write` runs
// leaves an existing directory as it was and a new one absent); `write` returns the files it
// wrote under the directory it is given, and so does this, at their final places.
std::vector<fs::path> write_out_directory(
    const fs::path& out_dir, const std::function<std::vector<fs::path>(const fs::path&)>& write) {
  std::vector<fs::path> files;
  fs::path staged_in;
  util::fill_directory_durably(out_dir, [&](const fs::path& dir) {
    staged_in = dir;
    files = write(dir);
  });
  for (fs::path& file : files) file = out_dir / file.lexically_relative(staged_in);
  return files;
}

struct RunFlags {
  std::string db = "millflow.db";
  int jobs = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  int threads_per_task = 1;
  int retries = 0;
  std::string executor;  // overrides the campaign's executor.kind
  double poll_interval_s = 10.0;
  std::string run_dir;               // batch jobs' run directory; default <db>.jobs
  std::vector<std::string> force;    // task kinds or task key prefixes
  std::optional<std::string> until;  // a task kind; `--until ""` is no kind, not "no --until"
};

constexpr int kMaxJobs = 1024;
constexpr int kMaxRetries = 100;

// The --db of a command that reads an existing database, checked (engine/database_path.hpp)
// before the command opens or creates anything.
fs::path existing_database(const std::string& given) {
  return engine::resolve_database(given, engine::DatabaseUse::existing);
}

void add_db_option(CLI::App* command, std::string& db) {
  command->add_option("--db", db, "Database file (default ./millflow.db)");
}

void add_selection_options(CLI::App* command, RunFlags& flags) {
  command->add_option("--force", flags.force,
                      "Run these cached tasks again: a task kind, or a task key or its prefix "
                      "(repeatable)");
  command->add_option("--until", flags.until,
                      "Run only the tasks of this kind and the tasks they need; the rest stay "
                      "pending");
}

// --force and --until as run options, each checked: a kind must be registered, a key prefix must
// name a task of the plan or of the store.
engine::RunOptions selection(const engine::Registry& registry,
                             const std::vector<engine::TaskSpec>& planned, const RunFlags& flags) {
  engine::RunOptions options;
  std::vector<engine::ValidationError> errors;
  for (const auto& name : flags.force) {
    if (registry.kinds.contains(name)) {
      options.force.kinds.push_back(name);
      continue;
    }
    // An empty prefix would be the prefix of every key: `--force ""` forced the whole campaign.
    const bool planned_key =
        !name.empty() && std::any_of(planned.begin(), planned.end(), [&](const auto& spec) {
          return spec.key.rfind(name, 0) == 0;
        });
    bool stored_key = false;
    if (!planned_key && !name.empty() && fs::exists(flags.db)) {
      auto db = engine::open_read_only(flags.db);
      try {
        engine::resolve_task(db, name);
        stored_key = true;
      } catch (const engine::InvalidInput&) {
      }
    }
    if (planned_key || stored_key) {
      options.force.key_prefixes.push_back(name);
    } else {
      errors.push_back(
          {"--force", "\"" + name + "\" is neither a task kind nor a task key",
           "name a kind (" + registry.kinds.names() + ") or a key from `millflow explain FILE`"});
    }
  }
  if (flags.until && !registry.kinds.contains(*flags.until)) {
    errors.push_back({"--until", "\"" + *flags.until + "\" is not a task kind",
                      "name one of: " + registry.kinds.names()});
  }
  if (!errors.empty()) throw engine::InvalidInput(errors);
  options.until = flags.until.value_or("");
  return options;
}

void add_run_options(CLI::App* command, RunFlags& flags) {
  add_db_option(command, flags.db);
  command->add_option("--jobs", flags.jobs, "Tasks running at once")
      ->check(CLI::Range(1, kMaxJobs));
  command
      ->add_option("--threads-per-task", flags.threads_per_task, "Threads of each task's own arena")
      ->check(CLI::Range(1, kMaxJobs));
  command->add_option("--retries", flags.retries, "Extra attempts of a failing task")
      ->check(CLI::Range(0, kMaxRetries));
  command
      ->add_option("--executor", flags.executor,
                   "local or slurm (overrides the campaign's executor.kind)")
      ->check(CLI::IsMember({"local", "slurm"}));
  command
      ->add_option("--poll-interval", flags.poll_interval_s,
                   "Slurm: seconds between polls of the jobs (default 10)")
      ->check(finite_between(0.1, 86400.0, "s"));
  command->add_option(
      "--run-dir", flags.run_dir,
      "Slurm: run directory on a filesystem the compute nodes share (default <db>.jobs)");
  add_selection_options(command, flags);
}

// The Slurm executor for this run, or null for the in-process launcher.
struct BatchJobs {
  std::unique_ptr<engine::SlurmCommands> commands;
  std::unique_ptr<engine::JobExecutor> executor;
};

BatchJobs batch_jobs(const ExecutorChoice& choice, const RunFlags& flags) {
  if (choice.kind != "slurm") return {};
  engine::SlurmSettings settings = choice.slurm;
  settings.run_dir =
      fs::absolute(flags.run_dir.empty() ? engine::jobs_dir(flags.db) : fs::path(flags.run_dir));
  settings.program = fs::read_symlink("/proc/self/exe");
  settings.poll_interval_s = flags.poll_interval_s;
  BatchJobs jobs;
  jobs.commands = engine::system_slurm_commands();
  jobs.executor = std::make_unique<engine::SlurmExecutor>(settings, *jobs.commands);
  return jobs;
}

TableFormat parse_format(const std::string& name) {
  if (name == "table") return TableFormat::table;
  if (name == "csv") return TableFormat::csv;
  return TableFormat::json;
}

int run_campaign(const engine::Registry& registry, engine::Campaign campaign, RunFlags flags) {
  flags.db = engine::resolve_database(flags.db, engine::DatabaseUse::create);
  const ExecutorChoice choice = choose_executor(campaign.document, flags.executor);
  // The stored document names the executor used, so `resume` goes on with it (and re-attaches).
  if (!flags.executor.empty()) campaign.document["executor"]["kind"] = flags.executor;
  const BatchJobs jobs = batch_jobs(choice, flags);
  engine::install_interrupt_handlers();
  engine::LiveProgress live(stderr);
  engine::PlainProgress plain(stderr);
  engine::SubmitOptions options;
  options.run = selection(registry, engine::plan_campaign(registry, campaign), flags);
  options.run.jobs = flags.jobs;
  options.run.threads_per_task = flags.threads_per_task;
  options.run.retries = flags.retries;
  options.run.stop_requested = engine::interrupt_requested;
  options.jobs = jobs.executor.get();
  options.progress = &terminal_or_plain(live, plain);
  const LogThrough logging(*options.progress);
  const auto summary = engine::submit_campaign(registry, campaign, flags.db, options);
  std::cout << "campaign " << campaign.name << ": " << summary.describe() << '\n';
  return summary.exit_code();
}

void add_validate(CLI::App& app, const engine::Registry& registry, std::optional<int>& code) {
  auto* command = app.add_subcommand("validate", "Check a campaign file; print every error");
  auto file = std::make_shared<std::string>();
  command->add_option("FILE", *file, "Campaign JSON file")->required();
  command->callback([&registry, &code, file] {
    code = guarded([&] {
      const auto campaign = engine::load_campaign_file(registry, *file);
      const auto tasks = engine::plan_campaign(registry, campaign);
      std::cout << fmt::format("{}: valid {} campaign \"{}\", {} planned tasks\n", *file,
                               campaign.format, campaign.name, tasks.size());
      return 0;
    });
  });
}

void add_submit(CLI::App& app, const engine::Registry& registry, std::optional<int>& code) {
  auto* command = app.add_subcommand("submit", "Run a campaign file (only what is not cached)");
  auto file = std::make_shared<std::string>();
  auto flags = std::make_shared<RunFlags>();
  auto dry = std::make_shared<bool>(false);
  command->add_option("FILE", *file, "Campaign JSON file")->required();
  add_run_options(command, *flags);
  command->add_flag("--dry-run", *dry, "Print per task kind what would run and why; write nothing");
  command->callback([&registry, &code, file, flags, dry] {
    code = guarded([&] {
      const auto campaign = engine::load_campaign_file(registry, *file);
      if (*dry) {
        const auto db = engine::resolve_database(flags->db, engine::DatabaseUse::create);
        const auto options = selection(registry, engine::plan_campaign(registry, campaign), *flags);
        const auto dry = engine::dry_run(registry, campaign, db, options);
        std::cout << dry.describe() << dry_run_cost(dry);
        return 0;
      }
      return run_campaign(registry, campaign, *flags);
    });
  });
}

void add_resume(CLI::App& app, const engine::Registry& registry, std::optional<int>& code) {
  auto* command = app.add_subcommand("resume", "Continue a stored campaign (default: the latest)");
  auto name = std::make_shared<std::string>();
  auto flags = std::make_shared<RunFlags>();
  command->add_option("CAMPAIGN", *name, "Campaign name");
  add_run_options(command, *flags);
  command->callback([&registry, &code, name, flags] {
    code = guarded([&] {
      return run_campaign(registry, engine::stored_campaign(existing_database(flags->db), *name),
                          *flags);
    });
  });
}

void add_exec(CLI::App& app, const engine::Registry& registry, std::optional<int>& code) {
  auto* command = app.add_subcommand("exec",
                                     "Run one task attempt from a task-spec file (what a batch job "
                                     "runs; never opens the database)");
  command->footer(
      "Exit codes: 0 done, 1 the task failed, 2 bad spec file, 75 stopped at a checkpoint on "
      "SIGUSR1/SIGTERM.");
  auto file = std::make_shared<std::string>();
  command->add_option("SPEC_FILE", *file, "Task-spec file written by the coordinator")->required();
  command->callback([&registry, &code, file] {
    engine::install_checkpoint_handlers();
    code = guarded([&] {
      return engine::execute_attempt(registry.kinds, *file, engine::interrupt_requested, std::cerr);
    });
  });
}

void add_status(CLI::App& app, std::optional<int>& code) {
  auto* command =
      app.add_subcommand("status", "Campaigns, or one campaign's tasks by kind and status");
  auto name = std::make_shared<std::string>();
  auto db = std::make_shared<std::string>("millflow.db");
  command->add_option("CAMPAIGN", *name, "Campaign name");
  add_db_option(command, *db);
  command->callback([&code, name, db] {
    code = guarded([&] {
      engine::print_status(existing_database(*db), *name, std::cout);
      return 0;
    });
  });
}

void add_query(CLI::App& app, std::optional<int>& code) {
  auto* command = app.add_subcommand("query", "Run one read-only SQL statement");
  auto sql = std::make_shared<std::string>();
  auto db = std::make_shared<std::string>("millflow.db");
  auto format = std::make_shared<std::string>("table");
  command->add_option("SQL", *sql, "SQL statement, e.g. \"SELECT * FROM task_results\"")
      ->required();
  add_db_option(command, *db);
  command->add_option("--format", *format, "table, csv or json")
      ->check(CLI::IsMember({"table", "csv", "json"}));
  command->callback([&code, sql, db, format] {
    code = guarded([&] {
      engine::run_query(existing_database(*db), *sql, parse_format(*format), std::cout);
      return 0;
    });
  });
}

void add_export(CLI::App& app, std::optional<int>& code) {
  auto* command =
      app.add_subcommand("export", "Write a campaign's parameters and results as CSV or JSON");
  auto name = std::make_shared<std::string>();
  auto db = std::make_shared<std::string>("millflow.db");
  auto format = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  command->add_option("CAMPAIGN", *name, "Campaign name")->required();
  add_db_option(command, *db);
  command->add_option("--format", *format, "csv or json")
      ->required()
      ->check(CLI::IsMember({"csv", "json"}));
  command->add_option("--out", *out, "Output directory")->required();
  command->callback([&code, name, db, format, out] {
    code = guarded([&] {
      const fs::path database = existing_database(*db);
      const auto files = write_out_directory(output_directory(*out), [&](const fs::path& dir) {
        return engine::export_campaign(database, *name, parse_format(*format), dir);
      });
      for (const auto& file : files) std::cout << file.string() << '\n';
      return 0;
    });
  });
}

void add_task_command(CLI::App& app, std::optional<int>& code, const std::string& name,
                      const std::string& help,
                      void (*print)(const fs::path&, const std::string&, std::ostream&)) {
  auto* command = app.add_subcommand(name, help);
  auto task = std::make_shared<std::string>();
  auto db = std::make_shared<std::string>("millflow.db");
  command->add_option("TASK", *task, "Task key or a unique prefix of it")->required();
  add_db_option(command, *db);
  command->callback([&code, task, db, print] {
    code = guarded([&] {
      print(existing_database(*db), *task, std::cout);
      return 0;
    });
  });
}

// explain TASK (a stored task) or explain FILE [TASK] (a campaign file, submitted or not).
void add_explain(CLI::App& app, const engine::Registry& registry, std::optional<int>& code) {
  auto* command = app.add_subcommand(
      "explain",
      "Why a task would run or not, with its hashed text: a stored task by key, or a campaign "
      "file's tasks (all of them, or one by key) before or after it was submitted");
  auto target = std::make_shared<std::string>();
  auto task = std::make_shared<std::string>();
  auto flags = std::make_shared<RunFlags>();
  command->add_option("TARGET", *target, "Task key (or a unique prefix), or a campaign file")
      ->required();
  command->add_option("TASK", *task, "With a campaign file: one of its tasks' key (or prefix)");
  add_db_option(command, flags->db);
  add_selection_options(command, *flags);
  command->callback([&registry, &code, target, task, flags] {
    code = guarded([&] {
      if (!fs::is_regular_file(*target)) {
        engine::print_explain(existing_database(flags->db), *target, std::cout);
        return 0;
      }
      const auto campaign = engine::load_campaign_file(registry, *target);
      const auto options = selection(registry, engine::plan_campaign(registry, campaign), *flags);
      // A campaign never submitted has no database yet: nothing is created for it.
      const fs::path db =
          fs::exists(flags->db) ? existing_database(flags->db) : fs::path(flags->db);
      const auto dry = engine::dry_run(registry, campaign, db, options);
      std::cout << (task->empty() ? dry.list() : dry.explain(*task));
      return 0;
    });
  });
}

void add_dag(CLI::App& app, std::optional<int>& code) {
  auto* command = app.add_subcommand(
      "dag", "Print a campaign's DAG as Graphviz dot: one node per task kind, or per task");
  auto name = std::make_shared<std::string>();
  auto db = std::make_shared<std::string>("millflow.db");
  auto every_task = std::make_shared<bool>(false);
  command->add_option("CAMPAIGN", *name, "Campaign name")->required();
  command->add_flag("--tasks", *every_task, "One node per task instead of one per kind");
  auto dot = std::make_shared<bool>(true);  // kept alive by the callback below
  command->add_flag("--dot", *dot, "Graphviz dot output (the only format; kept for old scripts)");
  add_db_option(command, *db);
  command->callback([&code, name, db, every_task, dot] {
    code = guarded([&] {
      engine::print_dag_dot(existing_database(*db), *name, *every_task, std::cout);
      return 0;
    });
  });
}

void add_gc(CLI::App& app, std::optional<int>& code) {
  auto* command = app.add_subcommand("gc", "Remove artifact files that no task references");
  auto db = std::make_shared<std::string>("millflow.db");
  auto dry = std::make_shared<bool>(false);
  add_db_option(command, *db);
  command->add_flag("--dry-run", *dry, "List them only");
  command->callback([&code, db, dry] {
    code = guarded([&] {
      const auto removed = engine::collect_garbage(existing_database(*db), *dry);
      for (const auto& digest : removed)
        std::cout << (*dry ? "would remove " : "removed ") << digest << '\n';
      std::cout << removed.size() << " unreferenced artifact file(s)\n";
      return 0;
    });
  });
}

// Copies the finished report task's files of a campaign out of the store.
void add_report(CLI::App& app, std::optional<int>& code) {
  auto* command = app.add_subcommand(
      "report", "Copy a campaign's report (figures, tables, index.md) into a directory");
  auto name = std::make_shared<std::string>();
  auto db = std::make_shared<std::string>("millflow.db");
  auto out = std::make_shared<std::string>("millflow-report");
  command->add_option("CAMPAIGN", *name, "Campaign name (default: the latest)");
  add_db_option(command, *db);
  command->add_option("--out", *out, "Output directory (default ./millflow-report)");
  command->callback([&code, name, db, out] {
    code = guarded([&] {
      const fs::path database = existing_database(*db);
      const fs::path out_dir = output_directory(*out);
      const std::string campaign =
          name->empty() ? engine::stored_campaign(database, "").name : *name;
      const auto reports = engine::finished_task_artifacts(database, campaign, "report");
      if (reports.empty()) {
        throw engine::InvalidInput(
            {{"", "campaign \"" + campaign + "\" has no finished report task",
              "run `millflow resume " + campaign + "` until its report task is done"}});
      }
      // A kill while the report is copied leaves a new directory absent and an existing one as it
      // was (util::fill_directory_durably says what a kill in its final renames leaves).
      util::fill_directory_durably(out_dir, [&](const fs::path& dir) {
        engine::copy_artifacts(database, reports.front().artifacts, dir);
      });
      std::cout << (out_dir / "index.md").string() << '\n';
      return 0;
    });
  });
}

// Writes a task's or a campaign's artifacts under their own names, for ParaView and scripts.
void add_files(CLI::App& app, std::optional<int>& code) {
  auto* command = app.add_subcommand(
      "files", "Write a task's or a campaign's files (VTK, CSV...) under their own names");
  command->footer(
      "A task's files go to DIR/<name> (e.g. DIR/vtk/particles.pvd), a campaign's to "
      "DIR/<kind>/<sweep point>_<key>/<name>, listed in DIR/tasks.csv.");
  auto name = std::make_shared<std::string>();
  auto db = std::make_shared<std::string>("millflow.db");
  auto out = std::make_shared<std::string>();
  command->add_option("TASK|CAMPAIGN", *name, "Campaign name, or task key or a unique prefix")
      ->required();
  add_db_option(command, *db);
  command->add_option("--out", *out, "Output directory")->required();
  command->callback([&code, name, db, out] {
    code = guarded([&] {
      const fs::path database = existing_database(*db);
      const auto files = write_out_directory(output_directory(*out), [&](const fs::path& dir) {
        return engine::export_files(database, *name, dir);
      });
      for (const auto& file : files) {
        if (file.extension() == ".pvd" || file.filename() == "tasks.csv")
          std::cout << file.string() << '\n';
      }
      std::cout << files.size() << " file(s) written under " << *out << '\n';
      return 0;
    });
  });
}

void add_logs(CLI::App& app, std::optional<int>& code) {
  auto* command = app.add_subcommand("logs", "A task's log lines, oldest first");
  auto task = std::make_shared<std::string>();
  auto db = std::make_shared<std::string>("millflow.db");
  command->add_option("TASK", *task, "Task key or a unique prefix of it")->required();
  add_db_option(command, *db);
  command->callback([&code, task, db] {
    code = guarded([&] {
      for (const auto& line : engine::task_log(existing_database(*db), *task))
        std::cout << line << '\n';
      return 0;
    });
  });
}

}  // namespace

LogThrough::LogThrough(engine::ProgressView& view) : previous_(spdlog::default_logger()) {
  spdlog::set_default_logger(engine::progress_logger(view));
}

LogThrough::~LogThrough() {
  spdlog::set_default_logger(previous_);
}

engine::ProgressView& terminal_or_plain(engine::LiveProgress& live, engine::PlainProgress& plain) {
  return ::isatty(STDERR_FILENO) ? static_cast<engine::ProgressView&>(live) : plain;
}

fs::path output_directory(const std::string& given) {
  constexpr const char* kFix = "pass a directory (it is created when missing)";
  if (given.empty()) throw engine::InvalidInput({{"--out", "the output directory is empty", kFix}});
  // The directory or, when it is missing, the nearest one above it that exists: where the
  // command's first write goes.
  fs::path existing = given;
  std::error_code error;
  while (!existing.empty() && !fs::exists(existing, error)) existing = existing.parent_path();
  if (existing.empty()) existing = ".";
  if (!fs::is_directory(existing, error)) {
    throw engine::InvalidInput(
        {{"--out", fmt::format("\"{}\" is not a directory", existing.string()), kFix}});
  }
  if (::access(existing.c_str(), W_OK | X_OK) != 0) {
    throw engine::InvalidInput(
        {{"--out",
          fmt::format("cannot write in \"{}\": {}", existing.string(), std::strerror(errno)),
          "pass a directory you can write"}});
  }
  return given;
}

int guarded(const std::function<int()>& body) {
  try {
    try {
      return body();
    } catch (const engine::sql::Error& error) {
      if (!engine::is_damaged_database_error(error.what())) throw;
      std::cerr << "millflow: the database is damaged (SQLite: " << error.what()
                << "); restore it from a backup (`sqlite3 <db> 'PRAGMA integrity_check'` shows "
                   "the damage)\n";
      return kBadInput;
    }
  } catch (const engine::InvalidInput& error) {
    std::cerr << "millflow: invalid input:\n" << error.what() << '\n';
    return kBadInput;
  } catch (const engine::SchemaTooNew& error) {
    std::cerr << "millflow: " << error.what() << '\n';
    return kBadInput;
  } catch (const engine::CoordinatorBusy& error) {
    std::cerr << "millflow: " << error.what() << '\n';
    return kBusy;
  } catch (const std::exception& error) {
    std::cerr << "millflow: " << error.what() << '\n';
    return 1;
  }
}

void add_engine_commands(CLI::App& app, const engine::Registry& registry,
                         std::optional<int>& exit_code) {
  add_validate(app, registry, exit_code);
  add_submit(app, registry, exit_code);
  add_resume(app, registry, exit_code);
  add_exec(app, registry, exit_code);
  add_status(app, exit_code);
  add_query(app, exit_code);
  add_export(app, exit_code);
  add_task_command(app, exit_code, "show", "A task's parameters, result, artifacts and lineage",
                   engine::print_show);
  add_explain(app, registry, exit_code);
  add_dag(app, exit_code);
  add_gc(app, exit_code);
  add_report(app, exit_code);
  add_files(app, exit_code);
  add_logs(app, exit_code);
}

}  // namespace millflow::cli
