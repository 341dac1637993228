// The task library's code version, recorded in every task's provenance.
namespace millflow::tasks {
const char* code_version() {
  return MILLFLOW_GIT_VERSION;
}
}  // namespace millflow::tasks
