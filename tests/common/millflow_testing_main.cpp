// millflow_testing: the millflow command line plus the engine's test task kinds and the
// "millflow-test" format (engine/testing_tasks.hpp), for tests that run a real process (the
// command line, crash safety, the Slurm cluster) and the engine benchmarks. The production
// millflow binary does not link the test kinds.
#include "cli/app.hpp"
#include "engine/testing_tasks.hpp"

int main(int argc, char** argv) {
  return millflow::cli::run(argc, argv, millflow::engine::add_testing);
}
