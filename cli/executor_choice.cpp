#include "cli/executor_choice.hpp"

#include <fmt/format.h>

#include <limits>

#include "engine/validation.hpp"

namespace millflow::cli {
namespace {

using nlohmann::json;

class BlockReader {
 public:
  explicit BlockReader(const json& block, std::string path = "/executor/slurm/")
      : block_(block), path_(std::move(path)) {}

  void text(const char* name, std::string& into) {
    if (const json* value = member(name, json::value_t::string, "a string"))
      into = value->get<std::string>();
  }
  void count(const char* name, int& into, int most = std::numeric_limits<int>::max()) {
    const std::string expected = most == std::numeric_limits<int>::max()
                                     ? "a positive integer"
                                     : fmt::format("an integer in [1, {}]", most);
    const json* value = member(name, json::value_t::number_unsigned, expected);
    if (value == nullptr) return;
    if (value->get<std::int64_t>() < 1 || value->get<std::int64_t>() > most) {
      wrong(name, expected);
      return;
    }
    into = value->get<int>();
  }
  void texts(const char* name, std::vector<std::string>& into) {
    const json* value = member(name, json::value_t::array, "an array of strings");
    if (value == nullptr) return;
    for (const auto& item : *value) {
      if (!item.is_string()) return wrong(name, "an array of strings");
      into.push_back(item.get<std::string>());
    }
  }
  void finish() const {
    if (!errors_.empty()) throw engine::InvalidInput(errors_);
  }

 private:
  const json* member(const char* name, json::value_t type, const std::string& expected) {
    if (!block_.contains(name)) return nullptr;
    const json& value = block_[name];
    const bool integer_wanted = type == json::value_t::number_unsigned;
    if (integer_wanted ? !value.is_number_integer() : value.type() != type) {
      wrong(name, expected);
      return nullptr;
    }
    return &value;
  }
  void wrong(const char* name, const std::string& expected) {
    errors_.push_back({path_ + name, "must be " + expected + ", got " + block_[name].dump(),
                       "fix the campaign file's executor block"});
  }

  const json& block_;
  std::string path_;  // of the block, ending in '/'
  std::vector<engine::ValidationError> errors_;
};

}  // namespace

ExecutorChoice choose_executor(const json& campaign_document, const std::string& kind_override) {
  ExecutorChoice choice;
  const json executor = campaign_document.value("executor", json::object());
  choice.kind =
      kind_override.empty() ? executor.value("kind", std::string("local")) : kind_override;
  if (choice.kind != "local" && choice.kind != "slurm") {
    throw engine::InvalidInput(
        {{"/executor/kind", "unknown executor \"" + choice.kind + "\"", "use local or slurm"}});
  }
  if (!executor.contains("slurm")) return choice;
  BlockReader slurm(executor["slurm"]);
  slurm.text("partition", choice.slurm.partition);
  slurm.text("account", choice.slurm.account);
  slurm.text("time_limit", choice.slurm.time_limit);
  slurm.text("memory", choice.slurm.memory);
  slurm.count("cpus_per_task", choice.slurm.cpus_per_task);
  slurm.count("max_in_flight", choice.slurm.max_in_flight);
  slurm.count("checkpoint_signal_s", choice.slurm.checkpoint_signal_s,
              engine::kSlurmMaxSignalLeadS);
  slurm.count("max_squeue_failures", choice.slurm.max_squeue_failures);
  slurm.texts("extra_args", choice.slurm.extra_args);
  slurm.finish();
  const json per_kind = executor["slurm"].value("per_kind", json::object());
  for (const auto& [kind, block] : per_kind.items()) {
    BlockReader own(block, "/executor/slurm/per_kind/" + kind + "/");
    engine::SlurmResources& resources = choice.slurm.per_kind[kind];
    own.text("time_limit", resources.time_limit);
    own.text("memory", resources.memory);
    own.count("cpus_per_task", resources.cpus_per_task);
    own.finish();
  }
  return choice;
}

}  // namespace millflow::cli
