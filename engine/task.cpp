#include "engine/task.hpp"

#include <stdexcept>

#include "engine/canonical_json.hpp"
#include "engine/validation.hpp"
#include "util/sha256.hpp"

namespace millflow::engine {
namespace {

// The key text's sections around the parameters.
constexpr std::string_view kParamsTag = "\nparams:", kUpstreamTag = "\nupstream:";

std::string join_keys(const std::vector<std::string>& keys) {
  std::string text;
  for (const auto& key : keys) {
    if (!text.empty()) text += ',';
    text += key;
  }
  return text;
}

}  // namespace

TaskSpec make_task_spec(std::string kind, std::string version, nlohmann::json params,
                        std::vector<std::string> upstream) {
  TaskSpec spec{.key = {},
                .kind = std::move(kind),
                .version = std::move(version),
                .params = std::move(params),
                .upstream = std::move(upstream),
                .key_text = {}};
  spec.key_text = "millflow-task 1\nkind:" + spec.kind + "\nversion:" + spec.version +
                  std::string(kParamsTag) + canonical_json(spec.params) +
                  std::string(kUpstreamTag) + join_keys(spec.upstream) + "\n";
  spec.key = util::sha256_hex(spec.key_text);
  return spec;
}

std::string_view key_text_params(std::string_view key_text) {
  const std::size_t tag = key_text.find(kParamsTag);
  const std::size_t end =
      tag == std::string_view::npos ? tag : key_text.find(kUpstreamTag, tag + kParamsTag.size());
  if (end == std::string_view::npos)
    throw std::logic_error("key_text_params: not a key text of make_task_spec");
  return key_text.substr(tag + kParamsTag.size(), end - tag - kParamsTag.size());
}

void KindRegistry::add(TaskKind kind) {
  const std::string name = kind.name;
  if (!kinds_.emplace(name, std::move(kind)).second) {
    throw std::logic_error("task kind registered twice: " + name);
  }
}

const TaskKind& KindRegistry::get(const std::string& name) const {
  const auto found = kinds_.find(name);
  if (found == kinds_.end())
    throw InvalidInput({{"", "unknown task kind \"" + name + "\"", "use one of: " + names()}});
  return found->second;
}

void KindRegistry::set_cost_model(const std::string& name, CostModel cost) {
  const auto found = kinds_.find(name);
  if (found == kinds_.end())
    throw std::logic_error("no task kind " + name + " to give a cost model");
  found->second.cost = std::move(cost);
}

std::string KindRegistry::names() const {
  std::string text;
  for (const auto& [name, kind] : kinds_) text += (text.empty() ? "" : ", ") + name;
  return text;
}

const std::string& Plan::add(const std::string& kind, nlohmann::json params,
                             std::vector<std::string> upstream) {
  for (const auto& key : upstream) {
    if (index_.count(key) == 0) {
      throw std::logic_error("plan: upstream task " + key + " of a " + kind +
                             " task is not in the plan");
    }
  }
  TaskSpec spec =
      make_task_spec(kind, kinds_->get(kind).version, std::move(params), std::move(upstream));
  const auto [where, inserted] = index_.emplace(spec.key, tasks_.size());
  if (inserted) tasks_.push_back(std::move(spec));
  return tasks_[where->second].key;
}

}  // namespace millflow::engine
