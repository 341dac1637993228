#pragma once
// millflow's campaign files: the field table (the contract, also rendered as
// schemas/campaign.schema.json), loading with every error reported at once, and the expansion of
// the `sweep` block into campaign points. Loading is pure: it reads the file and writes nothing.
#include <filesystem>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/json_validator.hpp"
#include "engine/sweep.hpp"

namespace millflow::tasks {

inline constexpr int campaign_format_version = 1;

// One point of a campaign's parameter study: the full settings there and the swept values.
using CampaignPoint = engine::SweepPoint;

// Every field of a campaign file: type, unit, range, default and description.
const engine::FieldTable& campaign_table();

// The JSON Schema of campaign files (what schemas/campaign.schema.json holds).
nlohmann::json campaign_json_schema();

// Reads and validates a campaign file. Returns the normalized campaign (defaults filled, the sweep
// block kept as written). Throws engine::InvalidInput with every error: JSON syntax (with line and
// column), unsupported version, fields (unknown, wrong type, out of range, missing), the sweep, and
// the cross-field checks, which hold for every point of the sweep.
nlohmann::json load_campaign(const std::filesystem::path& file);

// The same for a campaign held in memory (text or parsed document).
nlohmann::json parse_campaign(std::string_view text);
nlohmann::json validate_campaign(const nlohmann::json& document);

// The points of a validated campaign (one point without coordinates when it has no sweep).
std::vector<CampaignPoint> expand(const nlohmann::json& campaign);

}  // namespace millflow::tasks
