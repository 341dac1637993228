#include "cli/commands.hpp"

#include <fmt/format.h>
#include <unistd.h>

#include <iostream>

#include "cli/executor_choice.hpp"
#include "engine/attempt_files.hpp"
#include "engine/coordinator_lock.hpp"
#include "engine/inspect.hpp"
#include "engine/interrupt.hpp"
#include "engine/slurm_executor.hpp"
#include "engine/validation.hpp"

namespace millflow::cli {
namespace {

namespace fs = std::filesystem;
using engine::TableFormat;

constexpr int kBusy = 3;

struct RunFlags {
  std::string db = "millflow.db";
  int jobs = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  int threads_per_task = 1;
  int retries = 0;
  std::string executor;  // overrides the campaign's executor.kind
  double poll_interval_s = 10.0;
  std::string run_dir;  // batch jobs' run directory; default <db>.jobs
};

void add_db_option(CLI::App* command, std::string& db) {
  command->add_option("--db", db, "Database file (default ./millflow.db)");
}

void add_run_options(CLI::App* command, RunFlags& flags) {
  add_db_option(command, flags.db);
  command->add_option("--jobs", flags.jobs, "Tasks running at once")->check(CLI::PositiveNumber);
  command
      ->add_option("--threads-per-task", flags.threads_per_task, "Threads of each task's own arena")
      ->check(CLI::PositiveNumber);
  command->add_option("--retries", flags.retries, "Extra attempts of a failing task")
      ->check(CLI::NonNegativeNumber);
  command
      ->add_option("--executor", flags.executor,
                   "local or slurm (overrides the campaign's executor.kind)")
      ->check(CLI::IsMember({"local", "slurm"}));
  command
      ->add_option("--poll-interval", flags.poll_interval_s,
                   "Slurm: seconds between polls of the jobs (default 10)")
      ->check(CLI::PositiveNumber);
  command->add_option(
      "--run-dir", flags.run_dir,
      "Slurm: run directory on a filesystem the compute nodes share (default <db>.jobs)");
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

int run_campaign(const engine::Registry& registry, engine::Campaign campaign,
                 const RunFlags& flags) {
  const ExecutorChoice choice = choose_executor(campaign.document, flags.executor);
  // The stored document names the executor used, so `resume` goes on with it (and re-attaches).
  if (!flags.executor.empty()) campaign.document["executor"]["kind"] = flags.executor;
  const BatchJobs jobs = batch_jobs(choice, flags);
  engine::install_interrupt_handlers();
  engine::LiveProgress live(stderr);
  engine::PlainProgress plain(stderr);
  engine::SubmitOptions options;
  options.run.jobs = flags.jobs;
  options.run.threads_per_task = flags.threads_per_task;
  options.run.retries = flags.retries;
  options.run.stop_requested = engine::interrupt_requested;
  options.jobs = jobs.executor.get();
  options.progress = ::isatty(STDERR_FILENO) ? static_cast<engine::ProgressView*>(&live) : &plain;
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
  command->add_flag("--dry-run", *dry,
                    "Print the DAG size, what is cached and what would run; write nothing");
  command->callback([&registry, &code, file, flags, dry] {
    code = guarded([&] {
      const auto campaign = engine::load_campaign_file(registry, *file);
      if (*dry) {
        std::cout << engine::dry_run(registry, campaign, flags->db).describe() << '\n';
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
    code = guarded(
        [&] { return run_campaign(registry, engine::stored_campaign(flags->db, *name), *flags); });
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
      engine::print_status(*db, *name, std::cout);
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
      engine::run_query(*db, *sql, parse_format(*format), std::cout);
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
      for (const auto& file : engine::export_campaign(*db, *name, parse_format(*format), *out)) {
        std::cout << file.string() << '\n';
      }
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
      print(*db, *task, std::cout);
      return 0;
    });
  });
}

void add_dag(CLI::App& app, std::optional<int>& code) {
  auto* command = app.add_subcommand("dag", "Print a campaign's DAG");
  auto name = std::make_shared<std::string>();
  auto db = std::make_shared<std::string>("millflow.db");
  command->add_option("CAMPAIGN", *name, "Campaign name")->required();
  auto dot = std::make_shared<bool>(true);
  command->add_flag("--dot", *dot, "Graphviz dot output (the only format, also without the flag)");
  add_db_option(command, *db);
  command->callback([&code, name, db] {
    code = guarded([&] {
      engine::print_dag_dot(*db, *name, std::cout);
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
      const auto removed = engine::collect_garbage(*db, *dry);
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
      const std::string campaign = name->empty() ? engine::stored_campaign(*db, "").name : *name;
      const auto reports = engine::finished_task_artifacts(*db, campaign, "report");
      if (reports.empty()) {
        throw engine::InvalidInput(
            {{"", "campaign \"" + campaign + "\" has no finished report task",
              "run `millflow resume " + campaign + "` until its report task is done"}});
      }
      engine::copy_artifacts(*db, reports.front().artifacts, *out);
      std::cout << (fs::path(*out) / "index.md").string() << '\n';
      return 0;
    });
  });
}

}  // namespace

int guarded(const std::function<int()>& body) {
  try {
    return body();
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
  add_task_command(app, exit_code, "explain", "The hashed text of a task and why it would run",
                   engine::print_explain);
  add_dag(app, exit_code);
  add_gc(app, exit_code);
  add_report(app, exit_code);
}

}  // namespace millflow::cli
