#include "tasks/campaign_checks.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <string>

#include <fmt/format.h>

#include "dem/material.hpp"
#include "dem/wall_speed_controller.hpp"
#include "engine/json_validator.hpp"

#include "util/sphere.hpp"

namespace millflow::tasks {
namespace {

using engine::ValidationError;
using nlohmann::json;

std::string quantity(double value) {
  return fmt::format("{:.4g}", value);
}

bool related_paths(const std::string& a, const std::string& b) {
  const auto& shorter = a.size() <= b.size() ? a : b;
  const auto& longer = a.size() <= b.size() ? b : a;
  return longer.compare(0, shorter.size(), shorter) == 0 &&
         (longer.size() == shorter.size() || longer[shorter.size()] == '/');
}

struct BallClass {
  double diameter;
  double mass_fraction;
  std::string path;  // where the diameter is written
};

// Read access to the fields that passed their own rules.
class Campaign {
 public:
  Campaign(const json& document, const std::vector<ValidationError>& field_errors)
      : document_(document), field_errors_(field_errors) {}

  const json* node(const std::string& path) const {
    for (const auto& error : field_errors_) {
      if (related_paths(error.path, path)) return nullptr;
    }
    const json::json_pointer pointer(path);
    return document_.contains(pointer) ? &document_.at(pointer) : nullptr;
  }

  std::optional<double> number(const std::string& path) const {
    const auto* value = node(path);
    return value && value->is_number() ? std::optional(value->get<double>()) : std::nullopt;
  }

  std::optional<std::string> text(const std::string& path) const {
    const auto* value = node(path);
    return value && value->is_string() ? std::optional(value->get<std::string>()) : std::nullopt;
  }

  std::vector<std::string> materials() const {
    std::vector<std::string> names;
    if (const auto* defined = node("/materials"); defined && defined->is_object()) {
      for (const auto& [name, material] : defined->items()) names.push_back(name);
    }
    return names;
  }

  // The ball size classes, or nothing when the media are not usable.
  std::optional<std::vector<BallClass>> balls() const {
    if (const auto diameter = number("/media/diameter")) {
      return std::vector<BallClass>{{*diameter, 1.0, "/media/diameter"}};
    }
    const auto* classes = node("/media/size_distribution");
    if (node("/media") == nullptr || classes == nullptr || !classes->is_array())
      return std::nullopt;
    std::vector<BallClass> balls;
    for (std::size_t i = 0; i < classes->size(); ++i) {
      const auto path = "/media/size_distribution/" + std::to_string(i);
      balls.push_back({(*classes)[i].at("diameter").get<double>(),
                       (*classes)[i].at("mass_fraction").get<double>(), path + "/diameter"});
    }
    return balls;
  }

 private:
  const json& document_;
  const std::vector<ValidationError>& field_errors_;
};

double mean_diameter(const std::vector<BallClass>& balls) {
  double weighted = 0.0;
  double total = 0.0;
  for (const auto& ball : balls) {
    weighted += ball.mass_fraction * ball.diameter;
    total += ball.mass_fraction;
  }
  return weighted / total;
}

double largest_diameter(const std::vector<BallClass>& balls) {
  double largest = 0.0;
  for (const auto& ball : balls) largest = std::max(largest, ball.diameter);
  return largest;
}

// x rounded up to two significant digits, so that the figure shown is on the safe side.
double round_up_2(double x) {
  const double unit = std::pow(10.0, std::floor(std::log10(x)) - 1.0);
  return std::ceil(x / unit) * unit;
}

class ConsistencyChecker {
 public:
  explicit ConsistencyChecker(const Campaign& campaign) : campaign_(campaign) {}

  std::vector<ValidationError> run() {
    check_material_names();
    check_powder_given();
    check_powder_material();
    check_interaction_pairs();
    check_lifters();
    const auto balls = campaign_.balls();
    if (balls) {
      check_mass_fractions(*balls);
      check_balls_fit_mill(*balls);
      check_ball_count(*balls);
      check_sample_interval(*balls);
      check_macro_budget(*balls);
      check_stiffness_durations(*balls);
      check_powder_count();
    }
    check_region_rules(balls ? std::optional(mean_diameter(*balls)) : std::nullopt);
    check_at_least("/shear_cell/max_warmup_strain", "/shear_cell/warmup_strain");
    check_at_least("/shear_cell/convergence/max_strain", "/shear_cell/measure_strain");
    check_at_least("/shear_cell/stiffness/p95_overlap_fraction",
                   "/shear_cell/stiffness/mean_overlap_fraction");
    check_wall_measured_window();
    check_stiffness_sensitivity();
    check_wall_cell_height();
    check_cell_gravity();
    check_restitution_steps();
    return std::move(errors_);
  }

 private:
  void error(std::string path, std::string problem, std::string fix) {
    errors_.push_back({std::move(path), std::move(problem), std::move(fix)});
  }

  // A macro-only campaign: /shear_cell/enabled set to false.
  bool cells_disabled() const {
    const auto* enabled = campaign_.node("/shear_cell/enabled");
    return enabled != nullptr && enabled->is_boolean() && !enabled->get<bool>();
  }

  bool defined(const std::string& name) const {
    const auto names = campaign_.materials();
    return std::find(names.begin(), names.end(), name) != names.end();
  }

  void check_material_reference(const std::string& path) {
    const auto name = campaign_.text(path);
    if (!name || defined(*name) || campaign_.node("/materials") == nullptr) return;
    const auto names = campaign_.materials();
    const auto suggestion = engine::closest_match(*name, names);
    std::string known;
    for (const auto& n : names) known += (known.empty() ? "\"" : ", \"") + n + "\"";
    error(path, "unknown material \"" + *name + "\"",
          suggestion
              ? "did you mean \"" + *suggestion + "\"? (defined in /materials: " + known + ")"
              : "define it in /materials or use one of " + known);
  }

  void check_material_names() {
    for (const auto* path :
         {"/media/material", "/mill/liner_material", "/shear_cell/powder/material"}) {
      check_material_reference(path);
    }
    const auto* interactions = campaign_.node("/interactions");
    if (interactions == nullptr) return;
    for (std::size_t i = 0; i < interactions->size(); ++i) {
      for (const auto* side : {"/0", "/1"}) {
        check_material_reference("/interactions/" + std::to_string(i) + "/materials" + side);
      }
    }
  }

  // A macro-only campaign (shear cells disabled) needs no powder, nor its interactions.
  void check_powder_given() {
    const auto* shear_cell = campaign_.node("/shear_cell");
    if (shear_cell == nullptr || campaign_.node("/shear_cell/powder") != nullptr) return;
    if (cells_disabled()) return;
    error("/shear_cell/powder", "required field is missing when /shear_cell/enabled is true",
          "give the powder's material, diameter_ratio and load, or set /shear_cell/enabled to "
          "false for a macro-only campaign");
  }

  void check_powder_material() {
    const auto powder = campaign_.text("/shear_cell/powder/material");
    if (powder && powder == campaign_.text("/media/material")) {
      error("/shear_cell/powder/material", "the powder and the balls are both \"" + *powder + "\"",
            "give the powder its own material in /materials");
    }
  }

  static std::pair<std::string, std::string> pair_of(const std::string& a, const std::string& b) {
    return a <= b ? std::pair(a, b) : std::pair(b, a);
  }

  void check_interaction_pairs() {
    const auto* interactions = campaign_.node("/interactions");
    if (interactions == nullptr) return;
    std::vector<std::pair<std::string, std::string>> pairs;
    for (std::size_t i = 0; i < interactions->size(); ++i) {
      const auto path = "/interactions/" + std::to_string(i) + "/materials";
      const auto a = campaign_.text(path + "/0");
      const auto b = campaign_.text(path + "/1");
      if (!a || !b) continue;
      const auto pair = pair_of(*a, *b);
      const auto earlier = std::find(pairs.begin(), pairs.end(), pair);
      if (earlier != pairs.end()) {
        error(path,
              "the pair \"" + pair.first + "\", \"" + pair.second +
                  "\" is already defined by /interactions/" +
                  std::to_string(earlier - pairs.begin()),
              "keep one entry per material pair");
      }
      pairs.push_back(pair);
    }
    check_meeting_pairs(pairs);
  }

  // Balls meet balls and the liner in the mill, and powder in the shear cell (whose rough walls
  // are balls too); powder meets powder.
  void check_meeting_pairs(const std::vector<std::pair<std::string, std::string>>& pairs) {
    const auto media = campaign_.text("/media/material");
    const auto liner = campaign_.text("/mill/liner_material");
    const auto powder = campaign_.text("/shear_cell/powder/material");
    struct Meeting {
      std::optional<std::string> a, b;
      const char* where;
    };
    const Meeting meetings[] = {{media, media, "balls meet balls"},
                                {media, liner, "balls meet the liner"},
                                {media, powder, "balls meet powder in the shear cell"},
                                {powder, powder, "powder meets powder in the shear cell"}};
    std::vector<std::pair<std::string, std::string>> reported;
    for (const auto& meeting : meetings) {
      if (!meeting.a || !meeting.b || !defined(*meeting.a) || !defined(*meeting.b)) continue;
      const auto pair = pair_of(*meeting.a, *meeting.b);
      if (std::find(pairs.begin(), pairs.end(), pair) != pairs.end() ||
          std::find(reported.begin(), reported.end(), pair) != reported.end()) {
        continue;
      }
      reported.push_back(pair);
      error("/interactions",
            "no contact parameters for \"" + pair.first + "\" with \"" + pair.second + "\" (" +
                meeting.where + ")",
            "add an entry with \"materials\": [\"" + pair.first + "\", \"" + pair.second + "\"]");
    }
  }

  void check_lifters() {
    const auto count = campaign_.number("/mill/lifters/count");
    if (!count || *count == 0) return;
    const auto height = campaign_.number("/mill/lifters/height");
    const auto base = campaign_.number("/mill/lifters/base_width");
    const std::pair<const char*, const char*> dimensions[] = {{"height", "radial height"},
                                                              {"base_width", "width at the shell"}};
    for (const auto& [field, meaning] : dimensions) {
      const auto path = std::string("/mill/lifters/") + field;
      if (campaign_.node(path) == nullptr && campaign_.node("/mill/lifters") != nullptr) {
        error(path, "required field is missing when /mill/lifters/count > 0",
              std::string("add the lifter bar's ") + meaning + ", a number > 0 m");
      }
    }
    const auto diameter = campaign_.number("/mill/diameter");
    if (!diameter || !height || !base) return;
    if (*height >= *diameter / 4) {
      error("/mill/lifters/height",
            quantity(*height) + " m is not below half the mill radius (" + quantity(*diameter / 4) +
                " m)",
            "use lifters lower than " + quantity(*diameter / 4) + " m");
    }
    if (*count * *base >= std::numbers::pi * *diameter) {
      error("/mill/lifters/base_width",
            quantity(*count) + " lifters " + quantity(*base) + " m wide do not fit on the " +
                quantity(std::numbers::pi * *diameter) + " m shell circumference",
            "use fewer or narrower lifters");
    }
    check_lifter_faces(*height, *base);
  }

  // Inclined faces narrow the bar towards its top; the top must keep a positive width.
  void check_lifter_faces(double height, double base) {
    const auto angle = campaign_.number("/mill/lifters/face_angle_deg");
    if (!angle) return;
    const double top = base - 2.0 * height * std::tan(*angle * std::numbers::pi / 180.0);
    if (top > 0.0) return;
    const double widest = std::atan(base / (2.0 * height)) * 180.0 / std::numbers::pi;
    error("/mill/lifters/face_angle_deg",
          "faces at " + quantity(*angle) + " deg meet below the top of a " + quantity(height) +
              " m high, " + quantity(base) + " m wide lifter",
          "use a face angle below " + quantity(widest) + " deg, a wider base or a lower bar");
  }

  void check_mass_fractions(const std::vector<BallClass>& balls) {
    if (campaign_.node("/media/size_distribution") == nullptr) return;
    double sum = 0.0;
    for (const auto& ball : balls) sum += ball.mass_fraction;
    if (std::abs(sum - 1.0) > 1e-6) {
      error("/media/size_distribution", "the mass fractions sum to " + engine::quote_value(sum),
            "make them sum to 1 (within 1e-6)");
    }
  }

  void check_balls_fit_mill(const std::vector<BallClass>& balls) {
    const auto diameter = campaign_.number("/mill/diameter");
    if (diameter) {
      for (const auto& ball : balls) {
        if (ball.diameter <= *diameter / 10) continue;
        error(ball.path,
              quantity(ball.diameter) + " m balls are too big for a " + quantity(*diameter) +
                  " m mill",
              "use balls of at most " + quantity(*diameter / 10) +
                  " m (a tenth of the mill diameter)");
      }
    }
    const auto length = campaign_.number("/mill/length");
    const double largest = largest_diameter(balls);
    if (length && *length < 3 * largest * (1 - 1e-9)) {  // 0.15 m is 3 x 0.05 m, rounding aside
      error("/mill/length",
            "a " + quantity(*length) + " m slice is shorter than 3 diameters of the " +
                quantity(largest) + " m balls",
            "use a slice of at least " + quantity(3 * largest) + " m");
    }
  }

  // Balls in the charge at rest, from the fill and the bed's voids.
  std::optional<double> ball_count(const std::vector<BallClass>& balls) const {
    const auto fill = campaign_.number("/macro/fill");
    const auto diameter = campaign_.number("/mill/diameter");
    const auto length = campaign_.number("/mill/length");
    if (!fill || !diameter || !length) return std::nullopt;
    const double solid =
        *fill * std::numbers::pi / 4 * *diameter * *diameter * *length * (1 - bed_void_fraction);
    double count = 0.0;
    for (const auto& ball : balls)
      count += ball.mass_fraction * solid / util::sphere_volume_of_diameter(ball.diameter);
    return count;
  }

  void check_ball_count(const std::vector<BallClass>& balls) {
    const auto count = ball_count(balls);
    if (!count || *count >= min_balls_in_charge) return;
    error("/macro/fill",
          "fill " + quantity(*campaign_.number("/macro/fill")) + " holds only about " +
              fmt::format("{:.0f}", *count) + " balls in this mill slice",
          fmt::format("raise the fill, lengthen the slice or use smaller balls (a charge needs at "
                      "least {} balls)",
                      min_balls_in_charge));
  }

  void check_sample_interval(const std::vector<BallClass>& balls) {
    const auto interval = campaign_.number("/macro/sample_interval");
    const auto diameter = campaign_.number("/mill/diameter");
    const auto speed = campaign_.number("/macro/speed_fraction");
    const auto revolutions = campaign_.number("/macro/measure_revolutions");
    if (!interval || !diameter || !speed || !revolutions || *diameter <= mean_diameter(balls))
      return;
    const double critical_rpm = 42.3 / std::sqrt(*diameter - mean_diameter(balls));
    const double measured = *revolutions * 60.0 / (*speed * critical_rpm);
    if (measured / *interval >= min_flow_samples) return;
    error("/macro/sample_interval",
          quantity(*interval) + " s gives fewer than " + quantity(min_flow_samples) +
              " flow samples over the " + quantity(measured) + " s measurement",
          "use a sample interval of at most " + quantity(measured / min_flow_samples) + " s");
  }

  // The shortest contact duration of the media's interactions (see campaign_checks.hpp).
  std::optional<double> shortest_collision_time(const std::vector<BallClass>& balls) const {
    const auto media = campaign_.text("/media/material");
    const auto* interactions = campaign_.node("/interactions");
    if (!media || interactions == nullptr) return std::nullopt;
    const auto density = campaign_.number("/materials/" + *media + "/density");
    double smallest = std::numeric_limits<double>::infinity();
    for (const auto& ball : balls) smallest = std::min(smallest, ball.diameter);
    std::optional<double> shortest;
    for (const auto& interaction : *interactions) {
      const auto& pair = interaction.at("materials");
      const int media_sides = (pair[0] == *media ? 1 : 0) + (pair[1] == *media ? 1 : 0);
      if (media_sides == 0 || !interaction.contains("stiffness")) continue;
      const auto& stiffness = interaction.at("stiffness");
      double duration = 0.0;
      if (stiffness.contains("collision_time")) {
        duration = stiffness.at("collision_time").get<double>();
      } else if (stiffness.contains("normal") && density) {
        const double mass = *density * util::sphere_volume_of_diameter(smallest);
        const double effective = media_sides == 2 ? mass / 2 : mass;  // the liner is a wall
        duration = dem::collision_duration(stiffness.at("normal").get<double>(), effective,
                                           /*damping_ratio=*/0.0);  // the undamped estimate
      } else {
        continue;
      }
      shortest = std::min(shortest.value_or(duration), duration);
    }
    return shortest;
  }

  // What one macro run costs against the campaign's /limits.
  void check_macro_budget(const std::vector<BallClass>& balls) {
    const auto count = ball_count(balls);
    const auto max_particles = campaign_.number("/limits/max_particles_per_task");
    if (count && max_particles && *count > *max_particles) {
      error("/media",
            "about " + fmt::format("{:.3g}", *count) + " balls fill this mill slice, more than " +
                "/limits/max_particles_per_task = " + quantity(*max_particles),
            "use larger balls, a shorter slice or a lower fill, or raise "
            "/limits/max_particles_per_task if the machine has the memory");
    }
    const auto diameter = campaign_.number("/mill/diameter");
    const auto speed = campaign_.number("/macro/speed_fraction");
    const auto settle = campaign_.number("/macro/settle_time");
    const auto warmup = campaign_.number("/macro/warmup_revolutions");
    const auto measure = campaign_.number("/macro/measure_revolutions");
    const auto steps_per_collision = campaign_.number("/dem/steps_per_collision");
    const auto collision_time = shortest_collision_time(balls);
    if (!diameter || !speed || !settle || !warmup || !measure || !steps_per_collision ||
        !collision_time || *diameter <= mean_diameter(balls))
      return;
    const double critical_rpm = 42.3 / std::sqrt(*diameter - mean_diameter(balls));
    const double simulated = *settle + (*warmup + *measure) * 60.0 / (*speed * critical_rpm);
    const double time_step = *collision_time / *steps_per_collision;
    const double steps = simulated / time_step;
    const auto max_steps = campaign_.number("/limits/max_steps_per_task");
    if (max_steps && steps > *max_steps) {
      error("/macro",
            "a macro run takes about " + fmt::format("{:.3g}", steps) + " time steps (" +
                quantity(simulated) + " s at dt = " + quantity(time_step) +
                " s), more than /limits/max_steps_per_task = " + quantity(*max_steps),
            "measure fewer revolutions, use fewer steps per collision or softer contacts, or "
            "raise /limits/max_steps_per_task");
    }
    const auto vtk_interval = campaign_.number("/macro/vtk_interval");
    const auto max_files = campaign_.number("/limits/max_output_files_per_task");
    if (vtk_interval && max_files && simulated / *vtk_interval > *max_files) {
      error("/macro/vtk_interval",
            quantity(*vtk_interval) + " s writes about " +
                fmt::format("{:.3g}", simulated / *vtk_interval) + " VTK files over the " +
                quantity(simulated) + " s of a macro run, more than " +
                "/limits/max_output_files_per_task = " + quantity(*max_files),
            "use a VTK interval of at least " + quantity(simulated / *max_files) +
                " s, or raise /limits/max_output_files_per_task");
    }
  }

  // A cap (or an upper bound) below the value it caps cannot be met.
  void check_at_least(const std::string& cap_path, const std::string& value_path) {
    const auto cap = campaign_.number(cap_path);
    const auto value = campaign_.number(value_path);
    if (!cap || !value || *cap >= *value) return;
    error(cap_path, quantity(*cap) + " is below " + value_path + " = " + quantity(*value),
          "raise it to at least " + quantity(*value) + " or lower " + value_path);
  }

  // Rough walls drive the bulk to the site's rate over the measured window by setting their
  // speed every kMeasuredControlStrain (dem/wall_speed_controller.hpp): a window without two
  // such points cannot.
  void check_wall_measured_window() {
    const auto measure = campaign_.number("/shear_cell/measure_strain");
    if (campaign_.text("/shear_cell/boundary") != "walls" || !measure) return;
    const double least = 2.0 * dem::WallSpeedController::kMeasuredControlStrain;
    if (*measure >= least) return;
    error("/shear_cell/measure_strain",
          quantity(*measure) +
              " is too short for rough walls, whose speed answers the measured window's bulk "
              "rate every " +
              quantity(dem::WallSpeedController::kMeasuredControlStrain) + " strain",
          "raise it to at least " + quantity(least) + " (the walls' protocol measures " +
              quantity(dem::kRoughWallStrains.measure_strain) + ")");
  }

  // The extra stiff cells sit at sites the default cells have.
  void check_stiffness_sensitivity() {
    const std::string at = "/shear_cell/stiffness/sensitivity";
    const auto sites = campaign_.number(at + "/sites_per_region");
    const auto per_region = campaign_.number("/sites/per_region");
    if (sites && per_region && *sites > *per_region) {
      error(at + "/sites_per_region",
            quantity(*sites) + " is above /sites/per_region = " + quantity(*per_region) +
                ": the stiff cells go to sites the default cells have",
            "use at most " + quantity(*per_region) + " or raise /sites/per_region");
    }
    const auto* regions = campaign_.node(at + "/regions");
    const auto* chosen = campaign_.node("/sites/regions");
    if (regions == nullptr || chosen == nullptr) return;
    for (std::size_t i = 0; i < regions->size(); ++i) {
      const auto region = (*regions)[i].get<std::string>();
      if (std::find(chosen->begin(), chosen->end(), region) != chosen->end()) continue;
      error(at + "/regions/" + std::to_string(i),
            "region \"" + region + "\" gets no sites (it is not in /sites/regions)",
            "remove it or add it to /sites/regions");
    }
  }

  // Rough walls too close together bias the friction (dem::kRoughWallLeastHeight).
  void check_wall_cell_height() {
    const auto* size = campaign_.node("/shear_cell/size_diameters");
    if (campaign_.text("/shear_cell/boundary") != "walls" || size == nullptr || size->size() != 3)
      return;
    const double height = (*size)[1].get<double>();
    if (height >= dem::kRoughWallLeastHeight) return;
    error("/shear_cell/size_diameters/1",
          quantity(height) + " ball diameters is too short for rough walls, whose layers leave " +
              "too little bulk between them below " + quantity(dem::kRoughWallLeastHeight) +
              " (at 6 its friction came out 11% below Lees-Edwards')",
          "raise it to at least " + quantity(dem::kRoughWallLeastHeight) +
              " or use \"lees_edwards\"");
  }

  // Gravity pulls the bed against a floor, which only rough walls give: every Lees-Edwards cell
  // of the campaign would fail as it starts, after the macro runs (dem::ShearCellSetup).
  void check_cell_gravity() {
    const auto* gravity = campaign_.node("/shear_cell/gravity");
    if (gravity == nullptr || !gravity->is_boolean() || !gravity->get<bool>() ||
        campaign_.text("/shear_cell/boundary") == "walls" || cells_disabled())
      return;
    error("/shear_cell/gravity",
          "true needs rough walls: a Lees-Edwards cell is periodic along the gradient axis and has "
          "no floor to hold the bed's weight",
          "set it to false, or /shear_cell/boundary to \"walls\"");
  }

  // A contact damped near the critical (restitution near 0) lasts long against its stability
  // limit, its tangential oscillator's above all (dem::pair_stable_time_step_limit): the runs that
  // hold the pair would be refused as they start, after hours of a campaign's other tasks. The
  // steps it needs are exact where the pair holds a run's shortest contact, the one dt follows.
  void check_restitution_steps() {
    const auto* interactions = campaign_.node("/interactions");
    if (interactions == nullptr) return;
    const auto media = campaign_.text("/media/material");
    const auto liner = campaign_.text("/mill/liner_material");
    const auto powder = campaign_.text("/shear_cell/powder/material");
    for (std::size_t n = 0; n < interactions->size(); ++n) {
      const std::string at = fmt::format("/interactions/{}", n);
      const auto restitution = campaign_.number(at + "/restitution");
      const auto stiffness_ratio = campaign_.number(at + "/tangential_stiffness_ratio");
      const auto damping_ratio = campaign_.number(at + "/tangential_damping_ratio");
      const auto a = campaign_.text(at + "/materials/0");
      const auto b = campaign_.text(at + "/materials/1");
      if (!restitution || !stiffness_ratio || !damping_ratio || !a || !b) continue;
      const auto steps_needed = [&](double e) {
        const double zeta = dem::damping_ratio_for_restitution(e);
        const dem::PairParams unit{.normal_stiffness = 1.0,
                                   .tangential_stiffness = *stiffness_ratio,
                                   .damping_ratio = zeta,
                                   .tangential_damping_ratio = *damping_ratio};
        return std::ceil(dem::collision_duration(1.0, 1.0, zeta) /
                         dem::pair_stable_time_step_limit(unit, 1.0));
      };
      // The runs the pair meets in: the macro runs (balls and liner), the cells (balls, powder).
      const auto among = [&](std::initializer_list<std::optional<std::string>> materials) {
        const auto in = [&](const std::string& m) {
          return std::any_of(materials.begin(), materials.end(),
                             [&](const auto& x) { return x && *x == m; });
        };
        return in(*a) && in(*b);
      };
      const double needed = steps_needed(*restitution);
      std::vector<std::string> short_of;  // "path = steps" of each run that steps too coarsely
      double fewest = needed;
      for (const auto& [path, meets] :
           {std::pair{std::string("/dem/steps_per_collision"), among({media, liner})},
            std::pair{std::string("/shear_cell/steps_per_collision"), among({media, powder})}}) {
        const auto steps = campaign_.number(path);
        if (!meets || !steps || *steps >= needed) continue;
        short_of.push_back(path + " = " + quantity(*steps));
        fewest = std::min(fewest, *steps);
      }
      if (short_of.empty()) continue;
      // The least restitution the fewest steps hold: steps_needed falls as e rises.
      double low = *restitution, high = 1.0;
      for (int k = 0; k < 60; ++k) {
        const double mid = std::sqrt(low * high);
        (steps_needed(mid) <= fewest ? high : low) = mid;
      }
      const bool both = short_of.size() == 2;
      error(at + "/restitution",
            quantity(*restitution) + " damps the contact so near the critical that a run needs " +
                quantity(needed) + " steps per collision to be stable, more than " +
                short_of.front() + (both ? " and " + short_of.back() : ""),
            std::string(both ? "raise both" : "raise it") + " to at least " + quantity(needed) +
                ", or the restitution to at least " + fmt::format("{:.2g}", round_up_2(high)));
    }
  }

  // A stiffness given as k_n whose contact between the pair's reference particles (balls of the
  // media's mean diameter, grains of the powder's, a wall standing still) is shorter or longer
  // than any collision_time may be: the pair's runs would step at a fraction of that, without
  // end, or so soft that the particles pass through each other (1e-300 N/m: a run of no step).
  void check_stiffness_durations(const std::vector<BallClass>& balls) {
    const auto* interactions = campaign_.node("/interactions");
    // Balls already refused (too many, too big) make no reference particles worth a second error.
    const bool balls_refused = std::any_of(errors_.begin(), errors_.end(), [](const auto& e) {
      return related_paths(e.path, "/media");
    });
    if (interactions == nullptr || balls_refused) return;
    const double ball_diameter = mean_diameter(balls);
    const auto reference_mass = [&](const std::string& material) -> std::optional<double> {
      const auto density = campaign_.number("/materials/" + material + "/density");
      if (!density) return std::nullopt;
      if (campaign_.text("/media/material") == material)
        return *density * util::sphere_volume_of_diameter(ball_diameter);
      const auto ratio = campaign_.number("/shear_cell/powder/diameter_ratio");
      if (ratio && campaign_.text("/shear_cell/powder/material") == material)
        return *density * util::sphere_volume_of_diameter(*ratio * ball_diameter);
      return std::nullopt;  // a wall's material
    };
    for (std::size_t n = 0; n < interactions->size(); ++n) {
      const std::string path = fmt::format("/interactions/{}/stiffness/normal", n);
      const auto stiffness = campaign_.number(path);
      const auto restitution = campaign_.number(fmt::format("/interactions/{}/restitution", n));
      const auto material_a = campaign_.text(fmt::format("/interactions/{}/materials/0", n));
      const auto material_b = campaign_.text(fmt::format("/interactions/{}/materials/1", n));
      if (!stiffness || !restitution || !material_a || !material_b) continue;
      const auto mass_a = reference_mass(*material_a);
      const auto mass_b = reference_mass(*material_b);
      if (!mass_a && !mass_b) continue;
      const double effective =
          mass_a && mass_b ? dem::effective_mass(*mass_a, *mass_b) : mass_a.value_or(*mass_b);
      const double zeta = dem::damping_ratio_for_restitution(*restitution);
      const double duration = dem::collision_duration(*stiffness, effective, zeta);
      if (duration >= kShortestCollisionTime && duration <= kLongestCollisionTime) continue;
      const bool too_stiff = duration < kShortestCollisionTime;
      const double bound = too_stiff ? kShortestCollisionTime : kLongestCollisionTime;
      const double allowed = dem::stiffness_for_collision_duration(bound, effective, zeta);
      error(path,
            quantity(*stiffness) + " N/m gives the pair's reference particles a contact of " +
                quantity(duration) + " s, " + (too_stiff ? "shorter" : "longer") +
                " than a collision time may be (" + quantity(bound) + " s)",
            std::string("use ") + (too_stiff ? "at most " : "at least ") + quantity(allowed) +
                " N/m, or give the stiffness as collision_time");
    }
  }

  void check_powder_count() {
    const auto ratio = campaign_.number("/shear_cell/powder/diameter_ratio");
    const auto load = campaign_.number("/shear_cell/powder/load");
    const auto* size = campaign_.node("/shear_cell/size_diameters");
    if (!ratio || !load || size == nullptr || *load == 0.0) return;
    double cell = 1.0;  // in ball diameters cubed
    for (const auto& side : *size) cell *= side.get<double>();
    const double count = *load * bed_void_fraction * cell / util::sphere_volume_of_diameter(*ratio);
    if (count <= max_powder_particles) return;
    const double smallest =
        std::cbrt(*load * bed_void_fraction * cell / max_powder_particles * 6 / std::numbers::pi);
    error("/shear_cell/powder/diameter_ratio",
          "powder " + quantity(*ratio) + " times the ball diameter at load " + quantity(*load) +
              " puts about " + fmt::format("{:.0f}", count) + " particles in the shear cell",
          "use a diameter ratio of at least " + quantity(smallest) +
              ", a smaller cell or a lower load (at most " +
              fmt::format("{:.0f}", max_powder_particles) + " particles)");
  }

  // One rule set's values, each with the path it was written at (an alternative's own path, or
  // /sites/rules for what it takes from there).
  struct RuleValue {
    double value;
    std::string path;
  };

  std::optional<RuleValue> rule(const std::string& own_rules, const std::string& name) const {
    if (const auto value = campaign_.number(own_rules + "/" + name))
      return RuleValue{*value, own_rules + "/" + name};
    if (const auto value = campaign_.number("/sites/rules/" + name))
      return RuleValue{*value, "/sites/rules/" + name};
    return std::nullopt;
  }

  // Rules that leave part of the charge in no region, or make one region swallow the others, are
  // refused for the default set and for every alternative (an alternative's error is reported
  // only where it sets one of the values).
  void check_region_rules(const std::optional<double>& ball_diameter) {
    std::vector<std::string> rule_sets = {"/sites/rules"};
    if (const auto* alternatives = campaign_.node("/sites/alternatives");
        alternatives && alternatives->is_array()) {
      for (std::size_t i = 0; i < alternatives->size(); ++i)
        rule_sets.push_back("/sites/alternatives/" + std::to_string(i) + "/rules");
    }
    for (const std::string& own : rule_sets) check_rule_set(own, ball_diameter);
  }

  void check_rule_set(const std::string& own, const std::optional<double>& ball_diameter) {
    auto reported = [&](const RuleValue& a, const RuleValue& b) {
      return own == "/sites/rules" || a.path.starts_with(own) || b.path.starts_with(own);
    };
    const auto charge = rule(own, "charge_solid_fraction");
    const auto flight = rule(own, "flight_solid_fraction");
    if (charge && flight && charge->value >= flight->value && reported(*charge, *flight)) {
      error(charge->path,
            "a charge threshold of " + quantity(charge->value) +
                " is not below the free-flight threshold " + flight->path + " = " +
                quantity(flight->value) +
                ": the balls in flight between the two would belong to no region",
            "use a charge solid fraction below " + quantity(flight->value) +
                " (default 0.02), or raise " + flight->path);
    }
    const auto smallest = rule(own, "toe_min_radius_fraction");
    const auto search = rule(own, "toe_search_radius_fraction");
    if (smallest && search && smallest->value > search->value && reported(*smallest, *search)) {
      error(smallest->path,
            "a smallest toe radius of " + quantity(smallest->value) + " R exceeds the largest, " +
                search->path + " = " + quantity(search->value) + " R",
            "use a smallest toe radius of at most " + quantity(search->value) + " R, or widen " +
                search->path);
    }
    if (ball_diameter) check_liner_layer(own, *ball_diameter);
  }

  // The near-liner layer must leave the charge at rest a core for the bulk and cascading regions.
  void check_liner_layer(const std::string& own, double ball_diameter) {
    const auto layer = rule(own, "liner_layer_diameters");
    const auto fill = campaign_.number("/macro/fill");
    const auto diameter = campaign_.number("/mill/diameter");
    if (!layer || !fill || !diameter || !(own == "/sites/rules" || layer->path.starts_with(own)))
      return;
    const double depth = 0.5 * *diameter * (1.0 - std::cos(0.5 * segment_angle(*fill)));
    if (layer->value * ball_diameter < 0.5 * depth) return;
    error(layer->path,
          "a near-liner layer " + quantity(layer->value) + " ball diameters (" +
              quantity(layer->value * ball_diameter) + " m) thick is half or more of the " +
              quantity(depth) + " m deep charge at fill " + quantity(*fill) +
              ": it would leave no bulk or cascading region",
          "use a layer of fewer than " + quantity(0.5 * depth / ball_diameter) + " ball diameters");
  }

  // The central angle theta of the circular segment that holds a fraction `fill` of the disc:
  // fill = (theta - sin theta) / (2 pi), by bisection.
  static double segment_angle(double fill) {
    double low = 0.0, high = 2.0 * std::numbers::pi;
    for (int i = 0; i < 60; ++i) {
      const double mid = 0.5 * (low + high);
      ((mid - std::sin(mid)) / (2.0 * std::numbers::pi) < fill ? low : high) = mid;
    }
    return 0.5 * (low + high);
  }

  const Campaign& campaign_;
  std::vector<ValidationError> errors_;
};

}  // namespace

std::vector<engine::ValidationError> check_campaign_consistency(
    const nlohmann::json& campaign, const std::vector<ValidationError>& field_errors) {
  return ConsistencyChecker(Campaign(campaign, field_errors)).run();
}

}  // namespace millflow::tasks
