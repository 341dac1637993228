// The millflow executable: a thin main over millflow_cli.
#include "cli/app.hpp"

int main(int argc, char** argv) {
  return millflow::cli::run(argc, argv);
}
