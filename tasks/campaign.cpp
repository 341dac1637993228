#include "tasks/campaign.hpp"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <optional>
#include <set>
#include <sstream>

#include "engine/files.hpp"
#include "engine/json_text.hpp"
#include "engine/slurm_executor.hpp"
#include "tasks/campaign_checks.hpp"

namespace millflow::tasks {
namespace {

using engine::above;
using engine::at_least;
using engine::at_most;
using engine::below;
using engine::Field;
using engine::FieldType;
using engine::ValidationError;
using nlohmann::json;

// The most strain a cell's warm-up or measurement may be given. The defaults are 2-8 strains; a
// bound keeps a mistyped strain (1e308) from reaching the cell, whose step count would overflow
// (dem::ShearCell refuses more than 2^53 steps).
constexpr double kMostCellStrain = 1000.0;
// The least strain a cell measures: any positive one passed, and 5e-324 failed in the cell ("less
// than two time steps") after the macro runs; a measurement needs some batches of strain for its
// mean and standard error (dem/batch_means.hpp), and the campaigns measure 1-8.
constexpr double kLeastMeasuredStrain = 0.01;

const char* const material_name = "[a-z][a-z0-9_]*";
const std::vector<std::string> flow_regions = {"bulk", "shoulder",    "cascading",
                                               "toe",  "cataracting", "near_liner"};

std::vector<engine::FieldRule> material_fields() {
  return {
      Field("/materials", FieldType::object, "the materials, by name")
          .required()
          .pattern(material_name)
          .items(1, {})
          .hint("names are lower-case letters, digits and '_', starting with a letter"),
      Field("/materials/*", FieldType::object, "one material"),
      Field("/materials/*/density", FieldType::number, "material density")
          .unit("kg/m^3")
          .required()
          .range(at_least(100), at_most(30000)),
      Field("/interactions", FieldType::array, "contact parameters per material pair")
          .required()
          .items(1, {}),
      Field("/interactions/*", FieldType::object, "contact parameters of one material pair"),
      Field("/interactions/*/materials", FieldType::array,
            "the pair's two material names (the same name twice for a material with itself)")
          .required()
          .items(2, 2),
      Field("/interactions/*/materials/*", FieldType::string, "a material name")
          .pattern(material_name),
      Field("/interactions/*/restitution", FieldType::number, "normal coefficient of restitution")
          .required()
          .range(above(0), at_most(1)),
      Field("/interactions/*/friction", FieldType::number, "Coulomb friction coefficient")
          .required()
          .range(at_least(0), at_most(2)),
      Field("/interactions/*/stiffness", FieldType::object, "normal contact stiffness")
          .required()
          .exactly_one_of({"collision_time", "normal"}),
      Field("/interactions/*/stiffness/collision_time", FieldType::number,
            "collision time of two reference particles of the pair (each of its material's mean "
            "diameter; "
            "a wall counts as the particle alone), from which the normal stiffness is chosen")
          .unit("s")
          .range(at_least(kShortestCollisionTime), at_most(kLongestCollisionTime)),
      Field("/interactions/*/stiffness/normal", FieldType::number, "normal spring stiffness k_n")
          .unit("N/m")
          .range(above(0), {}),
      Field("/interactions/*/tangential_stiffness_ratio", FieldType::number,
            "ratio of tangential to normal stiffness k_t/k_n")
          .defaults(0.2857142857)
          .range(above(0), at_most(1)),
      Field("/interactions/*/tangential_damping_ratio", FieldType::number,
            "ratio of tangential to normal damping C_t/C_n")
          .defaults(0.5)
          .range(at_least(0), at_most(1)),
  };
}

std::vector<engine::FieldRule> macro_fields() {
  return {
      Field("/dem", FieldType::object, "DEM settings").defaults(json::object()),
      Field("/dem/steps_per_collision", FieldType::integer,
            "time steps per collision time (dt = t_c / N)")
          .defaults(20)
          .range(at_least(20), at_most(1000)),
      Field("/dem/neighbor_skin_fraction", FieldType::number,
            "neighbour-list skin as a fraction of the smallest particle diameter")
          .defaults(0.3)
          .range(at_least(0.01), at_most(2))
          .or_words({"auto"})
          .hint("\"auto\" keeps the cheapest skin by trial in each shear cell and macro run "
                "(docs/shear_cells.md)"),
      Field("/dem/seed", FieldType::integer, "random seed, combined with each task's key")
          .defaults(1)
          .range(at_least(0), at_most(4294967295.0)),
      Field("/mill", FieldType::object, "the mill").required(),
      Field("/mill/diameter", FieldType::number, "inner diameter of the mill shell")
          .unit("m")
          .required()
          .range(at_least(0.1), at_most(15)),
      Field("/mill/length", FieldType::number, "axial length of the simulated mill slice")
          .unit("m")
          .required()
          .range(above(0), at_most(20)),
      Field("/mill/axial_ends", FieldType::enumeration, "axial boundaries of the slice")
          .defaults("periodic")
          .choices({"periodic", "walls"}),
      Field("/mill/liner_material", FieldType::string, "material of the shell liner and lifters")
          .required()
          .pattern(material_name),
      Field("/mill/lifters", FieldType::object, "lifter bars on the shell")
          .defaults(json::object()),
      Field("/mill/lifters/count", FieldType::integer, "number of lifter bars (evenly spaced)")
          .defaults(0)
          .range(at_least(0), at_most(200)),
      Field("/mill/lifters/height", FieldType::number, "radial height of a lifter bar")
          .unit("m")
          .range(above(0), at_most(1)),
      Field("/mill/lifters/base_width", FieldType::number, "width of a lifter bar at the shell")
          .unit("m")
          .range(above(0), at_most(1)),
      Field("/mill/lifters/face_angle_deg", FieldType::number,
            "angle of the lifter faces from the radial direction (0: rectangular bar)")
          .unit("deg")
          .defaults(0.0)
          .range(at_least(0), below(60)),
      Field("/media", FieldType::object, "the grinding media (balls)")
          .required()
          .exactly_one_of({"diameter", "size_distribution"}),
      Field("/media/material", FieldType::string, "material of the balls")
          .required()
          .pattern(material_name),
      Field("/media/diameter", FieldType::number, "ball diameter (a single size)")
          .unit("m")
          .range(at_least(1e-4), at_most(0.5)),
      Field("/media/size_distribution", FieldType::array, "ball size classes").items(1, 20),
      Field("/media/size_distribution/*", FieldType::object, "one ball size class"),
      Field("/media/size_distribution/*/diameter", FieldType::number,
            "ball diameter of the size class")
          .unit("m")
          .required()
          .range(at_least(1e-4), at_most(0.5)),
      Field("/media/size_distribution/*/mass_fraction", FieldType::number,
            "mass fraction of the size class")
          .required()
          .range(above(0), at_most(1)),
      Field("/macro", FieldType::object, "the macroscale mill runs").required(),
      Field("/macro/fill", FieldType::number,
            "mill filling J (fraction of the mill volume taken by the charge at rest, voids "
            "included)")
          .required()
          .range(at_least(0.05), at_most(0.6)),
      Field("/macro/speed_fraction", FieldType::number,
            "mill speed as a fraction of the critical speed N_c = 42.3/sqrt(D - d) rpm")
          .required()
          .range(at_least(0.1), at_most(2)),
      Field("/macro/settle_time", FieldType::number,
            "time the charge settles before the mill turns")
          .unit("s")
          .defaults(0.5)
          .range(above(0), at_most(60)),
      Field("/macro/warmup_revolutions", FieldType::number, "mill revolutions before measuring")
          .defaults(2.0)
          .range(at_least(0), at_most(100)),
      Field("/macro/measure_revolutions", FieldType::number, "mill revolutions measured")
          .defaults(3.0)
          .range(above(0), at_most(1000)),
      Field("/macro/sample_interval", FieldType::number,
            "interval between flow samples for averaging")
          .unit("s")
          .defaults(0.01)
          .range(at_least(1e-4), at_most(10)),
      Field("/macro/vtk_interval", FieldType::number, "interval between VTK particle files")
          .unit("s")
          .defaults(0.1)
          .range(at_least(1e-3), {}),
      Field("/macro/checkpoint_interval_s", FieldType::number,
            "wall-clock interval between checkpoints")
          .unit("s")
          .defaults(60.0)
          .range(at_least(1), at_most(86400)),
  };
}

// What one task may cost before validation refuses it (campaign_checks.hpp estimates it). A
// campaign that means it raises them here.
std::vector<engine::FieldRule> limit_fields() {
  return {
      Field("/limits", FieldType::object,
            "the most one task may cost; raise a limit here to run beyond it")
          .defaults(json::object())
          .whole_campaign(),
      Field("/limits/max_steps_per_task", FieldType::number,
            "estimated DEM time steps of one macro run")
          .defaults(default_max_steps_per_task)
          .range(at_least(1), at_most(1e12)),
      Field("/limits/max_particles_per_task", FieldType::number, "balls in one macro run")
          .defaults(default_max_particles_per_task)
          .range(at_least(1), at_most(1e9)),
      Field("/limits/max_output_files_per_task", FieldType::number,
            "VTK particle files one macro run writes")
          .defaults(default_max_output_files_per_task)
          .range(at_least(1), at_most(1e7)),
  };
}

struct RegionRuleField {
  const char* name;
  const char* description;
  double default_value;
  std::optional<engine::Bound> minimum, maximum;
};

// The region rules (tasks/sites.hpp; docs/regions.md gives the reasons for the defaults).
const std::vector<RegionRuleField>& region_rule_fields() {
  static const std::vector<RegionRuleField> fields = {
      {"charge_solid_fraction", "solid fraction from which a cell belongs to the charge", 0.02,
       above(0), below(0.6)},
      {"flight_solid_fraction",
       "solid fraction below which the charge is in free flight (cataracting)", 0.2, above(0),
       below(0.6)},
      {"liner_layer_diameters", "thickness of the near-liner layer in ball diameters", 1.5,
       at_least(0), at_most(10)},
      {"toe_search_radius_fraction",
       "radius around the macro run's toe point searched for the impact zone, and the toe's "
       "largest radius, as a fraction of the mill radius",
       0.5, above(0), at_most(1)},
      {"impact_dissipation_fraction",
       "fraction of the highest dissipation density near the toe point from which a cell is in "
       "the impact zone",
       0.5, above(0), at_most(1)},
      {"toe_min_radius_fraction", "smallest toe radius as a fraction of the mill radius", 0.2,
       at_least(0), at_most(1)},
      {"shoulder_radius_fraction", "shoulder radius as a fraction of the mill radius", 0.2,
       at_least(0), at_most(1)},
      {"en_masse_max_slip",
       "largest |V - omega x r| / (|omega| |r|) of a cell moving en masse with the shell (bulk)",
       0.5, above(0), at_most(2)},
  };
  return fields;
}

// The rule fields below `prefix`: with their defaults for /sites/rules, without them for an
// alternative rule set (whose absent fields are the default set's).
std::vector<engine::FieldRule> region_rule_table(const std::string& prefix, bool with_defaults) {
  std::vector<engine::FieldRule> rules;
  for (const RegionRuleField& field : region_rule_fields()) {
    Field rule(prefix + "/" + field.name, FieldType::number, field.description);
    rule.range(field.minimum, field.maximum);
    if (with_defaults) rule.defaults(field.default_value);
    rules.push_back(rule);
  }
  return rules;
}

// Two alternatives that move the contested boundaries (toe, shoulder, en masse) both ways, so no
// conclusion rests on one choice.
json default_alternative_rules() {
  return json::array({{{"name", "narrow"},
                       {"rules",
                        {{"impact_dissipation_fraction", 0.7},
                         {"toe_min_radius_fraction", 0.1},
                         {"shoulder_radius_fraction", 0.1},
                         {"en_masse_max_slip", 0.3}}}},
                      {{"name", "wide"},
                       {"rules",
                        {{"impact_dissipation_fraction", 0.3},
                         {"toe_min_radius_fraction", 0.3},
                         {"shoulder_radius_fraction", 0.3},
                         {"en_masse_max_slip", 0.7}}}}});
}

std::vector<engine::FieldRule> site_fields() {
  std::vector<engine::FieldRule> rules = {
      Field("/sites", FieldType::object, "representative sites for the shear cells")
          .defaults(json::object()),
      Field("/sites/per_region", FieldType::integer, "sites chosen per flow region")
          .defaults(2)
          .range(at_least(1), at_most(20)),
      Field("/sites/regions", FieldType::array, "flow regions that get sites")
          .defaults(flow_regions)
          .items(1, flow_regions.size())
          .unique(),
      Field("/sites/regions/*", FieldType::enumeration, "a flow region").choices(flow_regions),
      Field("/sites/weight_by", FieldType::enumeration,
            "what a site's weight in the upscaling is: the balls' volume in it (solid_volume) or "
            "its geometric volume")
          .defaults("solid_volume")
          .choices({"solid_volume", "volume"}),
      Field("/sites/rules", FieldType::object, "the rules that split the charge into regions")
          .defaults(json::object()),
      Field("/sites/alternatives", FieldType::array,
            "alternative rule sets whose regions the results are also given for (sensitivity)")
          .defaults(default_alternative_rules())
          .items(0, 4),
      Field("/sites/alternatives/*", FieldType::object, "one alternative rule set"),
      Field("/sites/alternatives/*/name", FieldType::string, "the rule set's name")
          .required()
          .pattern("[a-z][a-z0-9_]*")
          .hint("names are lower-case letters, digits and '_', starting with a letter"),
      Field("/sites/alternatives/*/rules", FieldType::object,
            "the rules that differ from /sites/rules")
          .defaults(json::object()),
  };
  for (const auto& part : {region_rule_table("/sites/rules", true),
                           region_rule_table("/sites/alternatives/*/rules", false)}) {
    rules.insert(rules.end(), part.begin(), part.end());
  }
  return rules;
}

std::vector<engine::FieldRule> upscale_fields() {
  return {
      Field("/upscale", FieldType::object, "the upscaling of the shear cells to the mill")
          .defaults(json::object()),
      Field("/upscale/include_unsteady", FieldType::boolean,
            "whether cells that did not reach a steady state or converge count in the upscaling "
            "(they are listed either way)")
          .defaults(false),
  };
}

std::vector<engine::FieldRule> micro_fields() {
  std::vector<engine::FieldRule> rules = {
      Field("/average", FieldType::object, "coarse-graining over the mill cross-section")
          .defaults(json::object()),
      Field("/average/grid_cells", FieldType::array, "grid cells across the cross-section [nx, ny]")
          .defaults({40, 40})
          .items(2, 2),
      Field("/average/grid_cells/*", FieldType::integer, "grid cells along one axis")
          .range(at_least(4), at_most(400)),
      Field("/average/kernel_width_diameters", FieldType::number,
            "coarse-graining kernel width in ball diameters")
          .defaults(1.5)
          .range(at_least(0.5), at_most(5)),
  };
  const auto sites = site_fields();
  rules.insert(rules.end(), sites.begin(), sites.end());
  const std::vector<engine::FieldRule> cells = {
      Field("/shear_cell", FieldType::object, "the microscale shear cells").required(),
      Field("/shear_cell/enabled", FieldType::boolean,
            "whether the campaign runs the microscale shear cells below its sites (false stops at "
            "the sites)")
          .defaults(true),
      Field("/shear_cell/boundary", FieldType::enumeration,
            "boundaries in the gradient direction; \"walls\" (rough walls, the check on "
            "Lees-Edwards of docs/cell_validation.md, table 4; friction 5-7% below it at the "
            "same bulk I) needs size_diameters[1] of at least 8")
          .defaults("lees_edwards")
          .choices({"walls", "lees_edwards"}),
      Field("/shear_cell/size_diameters", FieldType::array,
            "cell size in ball diameters [x flow, y gradient, z spanwise]")
          .defaults({6.0, 8.0, 6.0})
          .items(3, 3),
      Field("/shear_cell/size_diameters/*", FieldType::number,
            "cell size along one axis in ball diameters")
          .range(at_least(3), at_most(30)),
      Field("/shear_cell/gravity", FieldType::boolean, "whether gravity acts in the shear cell")
          .defaults(false),
      Field("/shear_cell/warmup_strain", FieldType::number, "shear strain before measuring")
          .defaults(2.0)
          .range(at_least(0), at_most(kMostCellStrain)),
      Field("/shear_cell/max_warmup_strain", FieldType::number,
            "cap on the warm-up's strain: a cell that is not stationary by then is measured and "
            "reported steady = false (docs/shear_cells.md)")
          .defaults(6.0)
          .range(at_least(0), at_most(kMostCellStrain)),
      Field("/shear_cell/measure_strain", FieldType::number,
            "shear strain measured at least (the cell goes on to convergence)")
          .defaults(4.0)
          .range(at_least(kLeastMeasuredStrain), at_most(kMostCellStrain)),
      Field("/shear_cell/convergence", FieldType::object,
            "measure until the standard errors of friction and powder dissipation reach a target")
          .defaults(json::object()),
      Field("/shear_cell/convergence/standard_error", FieldType::number,
            "target relative standard error (batch means) of friction and powder dissipation")
          .defaults(0.03)
          .range(above(0), at_most(0.5)),
      Field("/shear_cell/convergence/max_strain", FieldType::number,
            "cap on the measured strain; an unconverged cell is reported converged = false")
          .defaults(8.0)
          .range(above(0), at_most(kMostCellStrain)),
      Field("/shear_cell/stiffness", FieldType::object,
            "stiffness policy of the shear cells (docs/shear_cells.md)")
          .defaults(json::object()),
      Field("/shear_cell/stiffness/policy", FieldType::enumeration,
            "\"overlap_bound\" raises every pair's k_n until the mean overlap at the cell's "
            "normal stress and shear rate is within the bound; \"campaign\" keeps /interactions")
          .defaults("overlap_bound")
          .choices({"overlap_bound", "campaign"}),
      Field("/shear_cell/stiffness/mean_overlap_fraction", FieldType::number,
            "bound on the mean overlap, as a fraction of the smaller diameter of a contact")
          .defaults(0.01)
          .range(at_least(1e-3), at_most(0.1))
          .hint("k_n grows as 1 / bound and the time step shrinks as its square root: 1e-3 already "
                "takes about 3 times the default's steps"),
      Field("/shear_cell/stiffness/p95_overlap_fraction", FieldType::number,
            "bound on the 95th percentile of the overlap; cells above it are flagged overlap_ok = "
            "false")
          .defaults(0.03)
          .range(at_least(1e-3), at_most(0.5))
          .hint(
              "the impact bound's k_n grows as 1 / bound^2 and the time step as much as the bound: "
              "1e-3 takes up to 30 times the default's steps"),
      Field("/shear_cell/stiffness/media_rigidity", FieldType::number,
            "\"overlap_bound\" also raises the media-media k_n to at least this times sigma_n "
            "d_m (the balls' rigidity k_n / (sigma_n d_m)); absent or 0: no such bound")
          .range(at_least(0), at_most(1e7)),
      // No default: a campaign without it plans no extra cells and keeps its tasks' parameters.
      Field("/shear_cell/stiffness/sensitivity", FieldType::object,
            "extra cells whose powder pairs (media-powder, powder-powder) are stiffer than the "
            "policy's k_n, at the same sites as the default cells: the upscaling reports how much "
            "cushioning and the powder's share of the power move, a systematic error the error "
            "bars do not carry (docs/method.md); absent: no such cells"),
      Field("/shear_cell/stiffness/sensitivity/factor", FieldType::number,
            "how many times the policy's k_n the powder pairs get in the extra cells")
          .defaults(4.0)
          .range(above(1), at_most(16)),
      Field("/shear_cell/stiffness/sensitivity/sites_per_region", FieldType::integer,
            "the first sites of each region that get an extra cell (at most /sites/per_region)")
          .defaults(1)
          .range(at_least(1), at_most(20)),
      Field("/shear_cell/stiffness/sensitivity/regions", FieldType::array,
            "the regions whose sites get extra cells (of /sites/regions; absent: all of them)")
          .items(1, flow_regions.size())
          .unique(),
      Field("/shear_cell/stiffness/sensitivity/regions/*", FieldType::enumeration, "a flow region")
          .choices(flow_regions),
      Field("/shear_cell/steps_per_collision", FieldType::integer,
            "time steps per collision time in the shear cells (dt = t_c / N; the macro runs' is "
            "/dem/steps_per_collision; the cells' energy balance error falls as 1/N)")
          .defaults(40)
          .range(at_least(20), at_most(1000)),
      Field("/shear_cell/checkpoint_interval_s", FieldType::number,
            "wall-clock interval between a cell's checkpoints")
          .unit("s")
          .defaults(60.0)
          .range(at_least(1), at_most(86400)),
      Field("/shear_cell/stress_control", FieldType::object, "the normal-stress control")
          .defaults(json::object()),
      Field("/shear_cell/stress_control/gain", FieldType::number,
            "gain of the normal-stress control (wall servo or Lees-Edwards barostat)")
          .defaults(0.5)
          .range(at_least(0.01), at_most(1))
          .hint("the loose fill compacts at a speed proportional to the gain: 0.01 takes 50 times "
                "the default's compaction steps"),
      Field("/shear_cell/powder", FieldType::object,
            "the powder in the shear cell (required unless /shear_cell/enabled is false)"),
      Field("/shear_cell/powder/material", FieldType::string, "material of the powder")
          .required()
          .pattern(material_name),
      Field("/shear_cell/powder/diameter_ratio", FieldType::number,
            "powder diameter as a fraction of the mean ball diameter")
          .required()
          .range(above(0.02), at_most(1)),
      Field("/shear_cell/powder/load", FieldType::number,
            "powder load U (fraction of the ball bed's voids filled with powder)")
          .required()
          .range(at_least(0), at_most(3)),
  };
  rules.insert(rules.end(), cells.begin(), cells.end());
  return rules;
}

std::vector<engine::FieldRule> executor_fields() {
  return {
      Field("/executor", FieldType::object, "where the tasks run")
          .defaults(json::object())
          .whole_campaign(),
      Field("/executor/kind", FieldType::enumeration, "executor kind")
          .defaults("local")
          .choices({"local", "slurm"}),
      Field("/executor/slurm", FieldType::object, "Slurm settings"),
      Field("/executor/slurm/partition", FieldType::string, "Slurm partition"),
      Field("/executor/slurm/account", FieldType::string, "Slurm account"),
      Field("/executor/slurm/time_limit", FieldType::string, "Slurm time limit per job")
          .pattern("([0-9]+-)?[0-9]+(:[0-9]{2}){0,2}")
          .hint("write minutes, HH:MM:SS or D-HH:MM:SS"),
      Field("/executor/slurm/cpus_per_task", FieldType::integer, "CPUs per Slurm job")
          .range(at_least(1), at_most(1024)),
      Field("/executor/slurm/memory", FieldType::string, "memory per Slurm job")
          .pattern("[0-9]+[KMGT]?")
          .hint("write a size such as 16G"),
      Field("/executor/slurm/per_kind", FieldType::object,
            "Slurm resources of one task kind's jobs, over the ones above (e.g. longer and larger "
            "for macro runs of a large mill than for powder cells)")
          .pattern("macro|average|sites|shear_cell|upscale|report")
          .hint("use a task kind: macro, average, sites, shear_cell, upscale or report"),
      Field("/executor/slurm/per_kind/*", FieldType::object, "one task kind's Slurm resources"),
      Field("/executor/slurm/per_kind/*/time_limit", FieldType::string,
            "Slurm time limit of this kind's jobs")
          .pattern("([0-9]+-)?[0-9]+(:[0-9]{2}){0,2}")
          .hint("write minutes, HH:MM:SS or D-HH:MM:SS"),
      Field("/executor/slurm/per_kind/*/cpus_per_task", FieldType::integer,
            "CPUs of this kind's Slurm jobs (also its tasks' threads)")
          .range(at_least(1), at_most(1024)),
      Field("/executor/slurm/per_kind/*/memory", FieldType::string,
            "memory of this kind's Slurm jobs")
          .pattern("[0-9]+[KMGT]?")
          .hint("write a size such as 16G"),
      Field("/executor/slurm/extra_args", FieldType::array, "extra sbatch arguments"),
      Field("/executor/slurm/extra_args/*", FieldType::string, "one sbatch argument"),
      Field("/executor/slurm/max_in_flight", FieldType::integer,
            "most Slurm jobs queued or running at once")
          .range(at_least(1), {}),
      // 0 would signal a job at its time limit, too late to checkpoint.
      Field("/executor/slurm/checkpoint_signal_s", FieldType::integer,
            "lead of the checkpoint signal before a Slurm job's time limit")
          .unit("s")
          .range(at_least(1), at_most(engine::kSlurmMaxSignalLeadS))
          .hint("jobs get sbatch --signal=B:USR1@N, which Slurm may send up to a minute early"),
      Field("/executor/slurm/max_squeue_failures", FieldType::integer,
            "failed squeue polls in a row before the coordinator stops")
          .range(at_least(1), {}),
  };
}

engine::FieldTable make_campaign_table() {
  std::vector<engine::FieldRule> rules = {
      Field("", FieldType::object, "a millflow campaign"),
      Field("/millflow_campaign", FieldType::integer, "campaign file format version")
          .required()
          .range(at_least(campaign_format_version), at_most(campaign_format_version))
          .whole_campaign(),
      Field("/name", FieldType::string, "the campaign name")
          .required()
          .pattern("[a-z0-9_-]+")
          .hint("use lower-case letters, digits, '_' and '-'")
          .whole_campaign(),
      Field("/description", FieldType::string, "a free-text description")
          .defaults("")
          .whole_campaign(),
  };
  const std::vector<engine::FieldRule> sweep = {
      Field("/sweep", FieldType::object,
            "the parameter study: the Cartesian product of the product axes and the zip groups")
          .opaque(),
  };
  for (const auto& part : {material_fields(), macro_fields(), micro_fields(), upscale_fields(),
                           executor_fields(), limit_fields(), sweep}) {
    rules.insert(rules.end(), part.begin(), part.end());
  }
  return engine::FieldTable(std::move(rules));
}

// A version this millflow cannot read makes every other message meaningless: report it alone.
void refuse_other_versions(const json& document) {
  if (!document.contains("millflow_campaign") || !document["millflow_campaign"].is_number()) return;
  const auto version = document["millflow_campaign"];
  if (version.get<double>() == campaign_format_version) return;
  throw engine::InvalidInput(
      {{"/millflow_campaign",
        "campaign format version " + engine::quote_value(version) + " is not supported",
        "this millflow reads version " + std::to_string(campaign_format_version) +
            " files; write \"millflow_campaign\": " + std::to_string(campaign_format_version)}});
}

std::string describe_point(const CampaignPoint& point) {
  std::string text;
  for (const auto& coordinate : point.coordinates) {
    text += (text.empty() ? "" : ", ") + coordinate.path + " = " +
            engine::quote_value(coordinate.value);
  }
  return text;
}

// The cross-field checks must hold wherever the sweep goes (the file without its sweep is checked
// as it stands); each error is reported once, at the first point that shows it.
void check_sweep_points(const json& campaign, std::vector<ValidationError>& errors) {
  std::set<std::string> seen;
  for (const auto& point : expand(campaign)) {
    for (auto error : check_campaign_consistency(point.document, {})) {
      if (!seen.insert(error.path + '\n' + error.problem).second) continue;
      error.problem += " (at sweep point " + describe_point(point) + ")";
      errors.push_back(std::move(error));
    }
  }
}

// The normalized campaign and every error of it (none when it is valid).
engine::ValidationResult check_campaign(const json& document) {
  if (!document.is_object()) {
    return {document,
            {{"", "expected an object, got " + engine::describe_value(document),
              "write the campaign as a JSON object {\"millflow_campaign\": 1, ...}"}}};
  }
  refuse_other_versions(document);
  auto [campaign, errors] = engine::validate(document, campaign_table());
  const auto sweep_errors = engine::check_sweep(campaign, campaign_table());
  errors.insert(errors.end(), sweep_errors.begin(), sweep_errors.end());
  const auto consistency_errors = check_campaign_consistency(campaign, errors);
  errors.insert(errors.end(), consistency_errors.begin(), consistency_errors.end());
  if (errors.empty() && campaign.contains("sweep")) check_sweep_points(campaign, errors);
  return {campaign, errors};
}

}  // namespace

const engine::FieldTable& campaign_table() {
  static const engine::FieldTable table = make_campaign_table();
  return table;
}

nlohmann::json campaign_json_schema() {
  auto schema = engine::to_json_schema(campaign_table());
  schema["title"] = "millflow campaign";
  // The table leaves the sweep block to the sweep's own checks; so does the schema.
  auto sweep = engine::sweep_json_schema();
  sweep["description"] = schema["properties"]["sweep"]["description"];
  schema["properties"]["sweep"] = sweep;
  return schema;
}

nlohmann::json validate_campaign(const nlohmann::json& document) {
  auto [campaign, errors] = check_campaign(document);
  if (!errors.empty()) throw engine::InvalidInput(std::move(errors));
  return campaign;
}

nlohmann::json parse_campaign(std::string_view text) {
  auto [document, errors] = engine::parse_json_text(text);
  auto [campaign, campaign_errors] = check_campaign(document);
  errors.insert(errors.end(), campaign_errors.begin(), campaign_errors.end());
  if (!errors.empty()) throw engine::InvalidInput(std::move(errors));
  return campaign;
}

nlohmann::json load_campaign(const std::filesystem::path& file) {
  return parse_campaign(engine::read_input_file(file));
}

std::vector<CampaignPoint> expand(const nlohmann::json& campaign) {
  return engine::expand_sweep(campaign, campaign_table());
}

}  // namespace millflow::tasks
