#include "tasks/cell_spec.hpp"

#include <stop_token>

#include <tbb/task_arena.h>

#include "engine/files.hpp"
#include "engine/json_text.hpp"
#include "engine/validation.hpp"
#include "method/sites.hpp"
#include "method/sites_result.hpp"
#include "tasks/campaign.hpp"
#include "tasks/campaign_checks.hpp"
#include "tasks/shear_cell.hpp"

namespace millflow::tasks {
namespace {

using engine::Field;
using engine::FieldType;
using nlohmann::json;

// The campaign's blocks a cell needs, under the same rules.
bool cell_block(const std::string& path) {
  for (const char* block : {"/materials", "/interactions", "/media", "/shear_cell", "/dem"}) {
    const std::string prefix = block;
    if (path == prefix || path.rfind(prefix + "/", 0) == 0) return true;
  }
  return false;
}

engine::FieldTable make_cell_spec_table() {
  std::vector<engine::FieldRule> rules = {
      Field("", FieldType::object, "one shear cell outside a campaign"),
      // A cell takes strain / (rate x dt) steps, and its k_n grows with the stress (the overlap
      // bound): the bounds keep one cell within hours, from I ~ 1e-4 to gas-like flow.
      Field("/shear_rate", FieldType::number, "the cell's target shear rate")
          .unit("1/s")
          .required()
          .range(engine::at_least(0.01), engine::at_most(1e4)),
      Field("/normal_stress", FieldType::number, "the normal stress the cell imposes")
          .unit("Pa")
          .required()
          .range(engine::at_least(1), engine::at_most(1e8)),
  };
  for (const engine::FieldRule& rule : campaign_table().rules()) {
    if (cell_block(rule.path)) rules.push_back(rule);
  }
  return engine::FieldTable(std::move(rules));
}

// A sites task's result holding the spec's one site, the slot that names it.
const json kSlot = {{"region", "cell"}, {"index", 0}};

// The spec's numbers are doubles already (the validator writes 20000 as 20000.0), so the typed
// drive keeps `millflow cell`'s output as it was.
json spec_site(const json& spec) {
  return method::drive_site_json(slot_site_id(kSlot), "cell",
                                 {.shear_rate = spec.at("shear_rate").get<double>(),
                                  .normal_stress = spec.at("normal_stress").get<double>()});
}

// The spec as a shear_cell task's parameters (its slot names the spec's one site).
json cell_task_params(const json& spec) {
  json params = spec;
  params["slot"] = kSlot;
  return params;
}

}  // namespace

const engine::FieldTable& cell_spec_table() {
  static const engine::FieldTable table = make_cell_spec_table();
  return table;
}

json parse_cell_spec(std::string_view text) {
  auto [document, errors] = engine::parse_json_text(text);
  if (!document.is_object()) {
    throw engine::InvalidInput({{"", "expected an object, got " + engine::describe_value(document),
                                 "write the spec as a JSON object {\"shear_rate\": ..., ...}"}});
  }
  auto [spec, field_errors] = engine::validate(document, cell_spec_table());
  errors.insert(errors.end(), field_errors.begin(), field_errors.end());
  const auto consistency = check_campaign_consistency(spec, errors);
  errors.insert(errors.end(), consistency.begin(), consistency.end());
  if (!errors.empty()) throw engine::InvalidInput(std::move(errors));
  return spec;
}

json load_cell_spec(const std::filesystem::path& file) {
  return parse_cell_spec(engine::read_input_file(file));
}

TaskCost cell_spec_cost(const json& spec) {
  return shear_cell_cost(cell_task_params(spec), spec_site(spec));
}

std::optional<json> run_cell_spec(const json& spec, const std::filesystem::path& out_dir,
                                  const CellRunHooks& hooks) {
  const json params = cell_task_params(spec);
  const std::vector<engine::TaskInput> inputs = {
      {.key = "spec",
       .kind = "sites",
       .result = method::sites_json_of({spec_site(spec)}),
       .artifacts = {}}};
  engine::TaskContext context{.key = "cell",
                              .params = params,
                              .inputs = inputs,
                              .work_dir = out_dir,
                              // The arena the caller runs this in (`millflow cell --threads`).
                              .threads = tbb::this_task_arena::max_concurrency(),
                              .attempt = 1,
                              .stop = hooks.stop,
                              .progress = hooks.progress,
                              .log = hooks.log};
  engine::TaskOutcome outcome = run_shear_cell(context);
  if (outcome.interrupted) return std::nullopt;
  return std::move(outcome.result);
}

}  // namespace millflow::tasks
