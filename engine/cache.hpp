#pragma once
// The cache decision: whether a task of a campaign is reused from the store or runs, and why.
// The runtime (engine/runtime.cpp), the dry run (engine/campaign.cpp) and `explain`
// (engine/inspect.cpp) all decide through CacheJudge::decide, so what they say cannot drift
// (docs/engine.md explains the rule).
//
// A task is cached when the store holds its key with status done, its result, and every artifact
// it recorded, each verified (size and SHA-256), and no --force names it. Otherwise it runs, and
// the reason is one of these (they exclude each other):
//   new                 its key is not in the store (or stored but never attempted); with an index
//                       of earlier tasks (dry run, explain) the reason names what changed against
//                       the nearest cached task of its kind: parameters changed (with the diff),
//                       kind version changed, upstream changed (which input)
//   not finished        stored but not done: failed, interrupted, left running, skipped, or
//                       pending with a recorded reason (e.g. an artifact found corrupt)
//   result missing      done, but no result stored
//   artifact missing or corrupt   done, but an artifact is gone or changed
//   forced              done and intact, but --force names its kind or key
#include <map>
#include <optional>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "engine/artifacts.hpp"
#include "engine/sqlite.hpp"
#include "engine/store.hpp"
#include "engine/task.hpp"

namespace millflow::engine {

enum class RunReason {
  cached,
  forced,
  artifact_bad,
  result_missing,
  not_finished,
  new_task,
  parameters_changed,
  version_changed,
  upstream_changed,
};

struct CacheDecision {
  RunReason reason = RunReason::new_task;
  std::string detail;             // e.g. the artifact, the error, the task compared with
  std::vector<std::string> diff;  // "/path: before -> after" or "input i: before -> after"

  bool cached() const { return reason == RunReason::cached; }
  // "cached", "new", "parameters changed", ...: the reason's name, for grouping.
  std::string summary() const;
  // "would run: parameters changed since sum task <key>" (or "would not run: ... (cached)"),
  // then the diff lines indented by two spaces.
  std::vector<std::string> lines() const;
};

// What --force names: task kinds (exact names) and task keys (full keys or prefixes).
struct ForceRule {
  std::vector<std::string> kinds;
  std::vector<std::string> key_prefixes;
  bool matches(const TaskSpec& spec) const;
  bool empty() const { return kinds.empty() && key_prefixes.empty(); }
};

// Cached tasks of each kind, read once per kind, to say what changed for a task that is not
// cached. Only the dry run and explain use it: the runtime needs the verdict, not the comparison.
class EarlierTasks {
 public:
  explicit EarlierTasks(sql::Connection& db) : db_(&db) {}
  // What differs between spec and an earlier cached task of its kind: `previous` when given and
  // cached (the task in the same place of the campaign's previous plan), else the one with
  // identical parameters if any (then upstream or version changed), else the one with the same
  // inputs and fewest changed parameters, else the fewest changed parameters over the kind.
  std::optional<CacheDecision> compare(const TaskSpec& spec, const TaskSpec* previous);

 private:
  struct Earlier {
    TaskSpec spec;
    std::map<std::string, std::string> leaves;  // parameters by JSON path, canonical values
  };
  struct OfKind {
    std::vector<Earlier> tasks;
    std::unordered_multimap<std::string, size_t> by_params;    // canonical parameters
    std::unordered_multimap<std::string, size_t> by_upstream;  // joined upstream keys
    std::unordered_map<std::string, size_t> by_key;
  };
  const OfKind& of_kind(const std::string& kind);

  sql::Connection* db_;
  std::map<std::string, OfKind> kinds_;
};

class CacheJudge {
 public:
  CacheJudge(const ArtifactStore& artifacts, ForceRule force, EarlierTasks* earlier = nullptr)
      : artifacts_(&artifacts), force_(std::move(force)), earlier_(earlier) {}

  // stored: what the store holds under spec.key (none when the key is not there); previous: the
  // task in the same place of the campaign's previous plan, if known (see EarlierTasks).
  CacheDecision decide(const TaskSpec& spec, const std::optional<StoredTask>& stored,
                       const TaskSpec* previous = nullptr) const;

 private:
  const ArtifactStore* artifacts_;
  ForceRule force_;
  EarlierTasks* earlier_;
};

// What `explain` prints for one task: its key, the exact hashed text, then decision.lines().
std::string explain_text(const TaskSpec& spec, const CacheDecision& decision);

// --until KIND: the tasks of the graph that do not run, those that are not of KIND, may not
// declare tasks (TaskKind::may_expand), and are not upstream of a task that is one of these.
std::unordered_set<std::string> beyond_until(const std::vector<const TaskSpec*>& graph,
                                             const KindRegistry& kinds, const std::string& until);

}  // namespace millflow::engine
