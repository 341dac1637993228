// The engine's code version, recorded in every task's provenance.
namespace millflow::engine {
const char* code_version() { return MILLFLOW_GIT_VERSION; }
}  // namespace millflow::engine
