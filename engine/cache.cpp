#include "engine/cache.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <limits>
#include <set>

#include "engine/canonical_json.hpp"

namespace millflow::engine {
namespace {

std::vector<std::string> leaf_diff(const std::map<std::string, std::string>& before,
                                   const std::map<std::string, std::string>& after) {
  std::set<std::string> paths;
  for (const auto& [path, value] : before) paths.insert(path);
  for (const auto& [path, value] : after) paths.insert(path);
  std::vector<std::string> lines;
  for (const auto& path : paths) {
    const auto old_value = before.count(path) ? before.at(path) : "(absent)";
    const auto new_value = after.count(path) ? after.at(path) : "(absent)";
    if (old_value != new_value)
      lines.push_back(fmt::format("{}: {} -> {}", path, old_value, new_value));
  }
  return lines;
}

std::string joined(const std::vector<std::string>& keys) {
  std::string text;
  for (const auto& key : keys) text += key + ",";
  return text;
}

std::vector<std::string> upstream_diff(const std::vector<std::string>& before,
                                       const std::vector<std::string>& after) {
  std::vector<std::string> lines;
  for (size_t i = 0; i < std::max(before.size(), after.size()); ++i) {
    const auto old_key = i < before.size() ? before[i] : "(none)";
    const auto new_key = i < after.size() ? after[i] : "(none)";
    if (old_key != new_key) lines.push_back(fmt::format("input {}: {} -> {}", i, old_key, new_key));
  }
  return lines;
}

// What changed from an earlier task to spec, most telling first: parameters, version, inputs.
CacheDecision changed_since(const TaskSpec& earlier, const std::vector<std::string>& params_diff,
                            const TaskSpec& spec) {
  CacheDecision decision;
  decision.detail = "since " + earlier.kind + " task " + earlier.key;
  if (!params_diff.empty()) {
    decision.reason = RunReason::parameters_changed;
    decision.diff = params_diff;
  } else if (earlier.version != spec.version) {
    decision.reason = RunReason::version_changed;
    decision.diff = {fmt::format("version: {} -> {}", earlier.version, spec.version)};
  } else {
    decision.reason = RunReason::upstream_changed;
    decision.diff = upstream_diff(earlier.upstream, spec.upstream);
  }
  return decision;
}

}  // namespace

std::string CacheDecision::summary() const {
  switch (reason) {
    case RunReason::cached:
      return "cached";
    case RunReason::forced:
      return "forced";
    case RunReason::artifact_bad:
      return "artifact missing or corrupt";
    case RunReason::result_missing:
      return "result missing";
    case RunReason::not_finished:
      return "not finished";
    case RunReason::new_task:
      return "new";
    case RunReason::parameters_changed:
      return "parameters changed";
    case RunReason::version_changed:
      return "kind version changed";
    case RunReason::upstream_changed:
      return "upstream changed";
  }
  return "unknown";
}

std::vector<std::string> CacheDecision::lines() const {
  if (cached()) return {"would not run: done, result and artifacts intact (cached)"};
  // "since <task>" reads on from the reason; other details follow a colon.
  const bool compared = reason == RunReason::parameters_changed ||
                        reason == RunReason::version_changed ||
                        reason == RunReason::upstream_changed;
  std::vector<std::string> lines{"would run: " + summary() +
                                 (detail.empty() ? "" : (compared ? " " : ": ") + detail)};
  for (const auto& line : diff) lines.push_back("  " + line);
  return lines;
}

bool ForceRule::matches(const TaskSpec& spec) const {
  for (const auto& kind : kinds) {
    if (spec.kind == kind) return true;
  }
  for (const auto& prefix : key_prefixes) {
    if (spec.key.rfind(prefix, 0) == 0) return true;
  }
  return false;
}

const EarlierTasks::OfKind& EarlierTasks::of_kind(const std::string& kind) {
  auto found = kinds_.find(kind);
  if (found != kinds_.end()) return found->second;
  OfKind& tasks = kinds_[kind];
  for (auto& record : find_tasks_of_kind(*db_, kind, TaskStatus::done)) {
    tasks.by_params.emplace(canonical_json(record.spec.params), tasks.tasks.size());
    tasks.by_upstream.emplace(joined(record.spec.upstream), tasks.tasks.size());
    tasks.by_key.emplace(record.spec.key, tasks.tasks.size());
    auto leaves = json_leaves(record.spec.params);
    tasks.tasks.push_back({std::move(record.spec), std::move(leaves)});
  }
  return tasks;
}

std::optional<CacheDecision> EarlierTasks::compare(const TaskSpec& spec, const TaskSpec* previous) {
  const OfKind& tasks = of_kind(spec.kind);
  auto other_than_spec = [&](size_t index) { return tasks.tasks[index].spec.key != spec.key; };
  if (previous != nullptr && previous->key != spec.key) {
    if (auto found = tasks.by_key.find(previous->key); found != tasks.by_key.end()) {
      const Earlier& earlier = tasks.tasks[found->second];
      return changed_since(earlier.spec, leaf_diff(earlier.leaves, json_leaves(spec.params)), spec);
    }
  }
  const auto same_params = tasks.by_params.equal_range(canonical_json(spec.params));
  for (auto it = same_params.first; it != same_params.second; ++it) {
    if (other_than_spec(it->second)) return changed_since(tasks.tasks[it->second].spec, {}, spec);
  }
  const auto leaves = json_leaves(spec.params);
  auto nearest = [&](auto&& candidates) -> std::optional<CacheDecision> {
    const Earlier* best = nullptr;
    std::vector<std::string> best_diff;
    size_t fewest = std::numeric_limits<size_t>::max();
    for (size_t index : candidates) {
      if (!other_than_spec(index)) continue;
      auto diff = leaf_diff(tasks.tasks[index].leaves, leaves);
      if (diff.size() < fewest) {
        fewest = diff.size();
        best = &tasks.tasks[index];
        best_diff = std::move(diff);
      }
    }
    if (best == nullptr) return std::nullopt;
    return changed_since(best->spec, best_diff, spec);
  };
  std::vector<size_t> same_inputs;
  const auto inputs = tasks.by_upstream.equal_range(joined(spec.upstream));
  for (auto it = inputs.first; it != inputs.second; ++it) same_inputs.push_back(it->second);
  std::sort(same_inputs.begin(), same_inputs.end());  // ties go to the smallest key
  if (auto decision = nearest(same_inputs)) return decision;
  std::vector<size_t> all(tasks.tasks.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = i;
  return nearest(all);
}

CacheDecision CacheJudge::decide(const TaskSpec& spec, const std::optional<StoredTask>& stored,
                                 const TaskSpec* previous) const {
  CacheDecision decision;
  const bool never_attempted =
      !stored || (stored->status == TaskStatus::pending && stored->attempts == 0);
  if (never_attempted) {
    if (earlier_ != nullptr) {
      if (auto changed = earlier_->compare(spec, previous)) return *changed;
    }
    decision.reason = RunReason::new_task;
    return decision;
  }
  if (stored->status != TaskStatus::done) {
    decision.reason = RunReason::not_finished;
    switch (stored->status) {
      case TaskStatus::failed:
        decision.detail = "the previous attempt failed: " + stored->error;
        break;
      case TaskStatus::interrupted:
        decision.detail = "the previous attempt was interrupted";
        break;
      case TaskStatus::running:
        decision.detail = "its last attempt never finished (coordinator stopped or still running)";
        break;
      case TaskStatus::skipped:
        decision.detail = "it was skipped because " + stored->error;
        break;
      default:
        decision.detail = stored->error.empty() ? "not finished yet" : stored->error;
    }
    return decision;
  }
  if (!stored->has_result) {
    decision.reason = RunReason::result_missing;
    decision.detail =
        "done, but the store holds no intact result for it (none, not JSON, or not its digest)";
    return decision;
  }
  for (const auto& artifact : stored->artifacts) {
    if (!artifacts_->verify(artifact)) {
      decision.reason = RunReason::artifact_bad;
      decision.detail = fmt::format("{} ({})", artifact.name, artifact.sha256);
      return decision;
    }
  }
  if (force_.matches(spec)) {
    decision.reason = RunReason::forced;
    decision.detail = "--force names it";
    return decision;
  }
  decision.reason = RunReason::cached;
  return decision;
}

std::string explain_text(const TaskSpec& spec, const CacheDecision& decision) {
  std::string text =
      "task " + spec.key + "\nhashed text (SHA-256 of exactly these bytes):\n" + spec.key_text;
  for (const auto& line : decision.lines()) text += line + "\n";
  return text;
}

std::unordered_set<std::string> beyond_until(const std::vector<const TaskSpec*>& graph,
                                             const KindRegistry& kinds, const std::string& until) {
  std::unordered_map<std::string, const TaskSpec*> by_key;
  for (const TaskSpec* spec : graph) by_key.emplace(spec->key, spec);
  std::unordered_set<std::string> needed;
  std::vector<const TaskSpec*> frontier;
  for (const TaskSpec* spec : graph) {
    const bool expands = kinds.contains(spec->kind) && kinds.get(spec->kind).may_expand;
    if (spec->kind == until || expands) frontier.push_back(spec);
  }
  while (!frontier.empty()) {
    const TaskSpec* spec = frontier.back();
    frontier.pop_back();
    if (!needed.insert(spec->key).second) continue;
    for (const auto& upstream : spec->upstream) {
      if (auto found = by_key.find(upstream); found != by_key.end())
        frontier.push_back(found->second);
    }
  }
  std::unordered_set<std::string> beyond;
  for (const TaskSpec* spec : graph) {
    if (needed.count(spec->key) == 0) beyond.insert(spec->key);
  }
  return beyond;
}

}  // namespace millflow::engine
