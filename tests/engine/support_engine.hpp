#pragma once
// Helpers shared by the engine tests: scratch directories, test campaigns, store reads.
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "engine/campaign.hpp"
#include "engine/testing_tasks.hpp"
#include "tests/common/scratch_dir.hpp"

namespace millflow::engine::testing {

using millflow::testing::ScratchDir;

Registry testing_registry();

// {"format": "millflow-test", "name": name, "tasks": tasks}
Campaign test_campaign(const std::string& name, nlohmann::json tasks);

// a -> b, a -> c, (b, c) -> d (sum tasks); a writes an artifact, and c carries a second parameter
// so that it is the one nearest task to any variant of itself.
nlohmann::json noted_diamond(int c_value);

RunSummary submit(const Campaign& campaign, const std::filesystem::path& db, int jobs = 2,
                  int retries = 0);

// One integer from a read-only SQL query.
std::int64_t count(const std::filesystem::path& db, const std::string& sql);
// The "sum" result of the campaign's task with these params (canonical JSON) and kind.
nlohmann::json result_of(const std::filesystem::path& db, const std::string& key);

}  // namespace millflow::engine::testing
