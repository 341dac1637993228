// The shear cell's warm-up: windows, the velocity profile and bulk shear rate they sample, and the
// wall-speed controller between them.
#include "dem/shear_cell.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "dem/shear_cell_geometry.hpp"
#include "dem/stationarity.hpp"
#include "util/sphere.hpp"

namespace millflow::dem {
using namespace shear_cell_detail;

void ShearCell::sample_profile(Profile& profile) const {
  const double y0 =
      walls() ? wall_layer_plane(system_, 0, wall_ball_count_ / 2) : system_.domain().lo.y();
  const double lo = y0 + 0.25 * gap(), hi = y0 + 0.75 * gap();
  const auto x = system_.positions();
  const auto v = system_.velocities();
  const auto m = system_.masses();
  const auto r = system_.radii();
  const auto groups = system_.particle_groups();
  const auto materials = system_.particle_materials();
  for (std::size_t p = 0; p < system_.size(); ++p) {
    if (groups[p] != kFreeParticle || x[p].y() < lo || x[p].y() >= hi) continue;
    const double y = x[p].y() - y0;
    profile.w += m[p];
    profile.wy += m[p] * y;
    profile.wyy += m[p] * y * y;
    profile.wv += m[p] * v[p].x();
    profile.wyv += m[p] * y * v[p].x();
    const double volume = util::sphere_volume_of_radius(r[p]);
    (materials[p] == powder_ ? profile.powder_volume : profile.media_volume) += volume;
  }
  profile.slab_volume += wall_area() * (hi - lo);
}

double ShearCell::bulk_shear_rate(const Profile& profile) {
  const double denominator = profile.w * profile.wyy - profile.wy * profile.wy;
  return denominator > 0.0 ? (profile.w * profile.wyv - profile.wy * profile.wv) / denominator
                           : 0.0;
}

void ShearCell::warm_up(double strain, int windows) {
  if (windows < 1)
    throw std::invalid_argument(
        fmt::format("shear cell: warm-up windows = {} must be >= 1", windows));
  WindowMeans previous;
  for (int w = 0; w < windows; ++w) {
    WarmUpWindow window = start_window(strain / windows);
    advance_window(window, window.steps);
    previous = finish_window(window, w, w > 0 ? &previous : nullptr);
  }
}

ShearCell::WarmUpWindow ShearCell::start_window(double strain) const {
  WarmUpWindow window;
  window.steps = steps_for_strain(strain);
  // The profile takes a while to answer a new wall speed: measure over the second half only.
  window.half = window.steps / 2;
  // Samples at every phase of the stress control's interval, not in step with it (the Lees-Edwards
  // barostat's stretches make the stress ring: sample_interval_across_control_phases).
  window.every = sample_interval_across_control_phases((window.steps - window.half) / 50,
                                                       control_->settings().interval_steps);
  return window;
}

void ShearCell::advance_window(WarmUpWindow& window, std::uint64_t max_steps) {
  compact();
  const std::uint64_t end = std::min(window.steps, window.done + max_steps);
  while (window.done < end) {
    // Up to the next sample: every `every` steps after `half`, and at the window's end.
    const std::uint64_t next_sample =
        window.done < window.half
            ? window.half
            : std::min(window.steps,
                       window.done + window.every - (window.done - window.half) % window.every);
    const std::uint64_t until = std::min(end, next_sample);
    if (walls() && window.done >= window.half) {
      // The wall loads are free: summed every step of the second half. (Sampled every `every`
      // steps they were read in step with the servo's interval, and its wall load then read
      // 20-70% above the true mean.)
      for (; window.done < until; ++window.done) {
        advance(1);
        window.shear_sum += shear_stress_now();
        window.normal_sum += normal_stress_now();
      }
    } else {
      advance(until - window.done);
      window.done = until;
    }
    if (window.done > window.half && (window.done == next_sample)) {
      sample_profile(window.profile);
      if (!walls()) {
        window.shear_sum += shear_stress_now();
        window.normal_sum += normal_stress_now();
      }
      window.samples += 1.0;
    }
  }
}

WindowMeans ShearCell::finish_window(const WarmUpWindow& window, int index,
                                     const WindowMeans* previous) {
  // The bed has sheared a window: nearer its steady state than the compacted one (and the first
  // window leaves the wall speed as it is, so the trials see the speed the run goes on at).
  if (index == 0) choose_neighbor_skin();
  const double measured = bulk_shear_rate(window.profile);
  const double stress_samples =
      walls() ? static_cast<double>(window.steps - window.half) : window.samples;
  const WindowMeans summary{
      .shear_stress = window.shear_sum / stress_samples,
      .normal_stress = window.normal_sum / stress_samples,
      .solid_fraction =
          (window.profile.media_volume + window.profile.powder_volume) / window.profile.slab_volume,
      .bulk_shear_rate = measured};
  spdlog::debug(
      "shear cell: warm-up window {}: solid fraction {:.4g}, shear stress {:.4g} Pa, normal stress "
      "{:.4g} Pa (target {:.4g}), bulk rate {:.4g} 1/s",
      index, summary.solid_fraction, summary.shear_stress, summary.normal_stress,
      setup_.normal_stress, measured);
  // The bulk of a bed that has lost contact with the walls does not follow them: leave the speed
  // until the servo has closed the gap.
  if (!walls() || summary.normal_stress < kClosingStressFraction * setup_.normal_stress)
    return summary;
  // Nor while the bed still compacts: the profile of a shrinking gap is not the steady one, and
  // answering it drove the walls to tens of m/s.
  if (previous == nullptr ||
      std::abs(summary.solid_fraction - previous->solid_fraction) > kCompactedFractionChange)
    return summary;
  const double speed = speed_controller_.update(measured, wall_speed_, gap());
  spdlog::debug(
      "shear cell: warm-up window {}: bulk fraction {:.4g} (last steady estimate; {} windows at "
      "this speed), wall speed {:.4g} -> {:.4g} m/s{}",
      index, speed_controller_.bulk_fraction(), speed_controller_.windows(), wall_speed_, speed,
      speed_controller_.settled() ? ", settled" : "");
  set_wall_speed(speed);
  return summary;
}

bool ShearCell::stationary(std::span<const WindowMeans> windows) const {
  const StationarityVerdict verdict =
      test_stationarity(windows, setup_.normal_stress, walls() ? setup_.shear_rate : 0.0);
  spdlog::debug(
      "shear cell: stationarity: shear stress {}, solid fraction {}, normal stress {}, bulk rate "
      "{}{}",
      verdict.shear_stress, verdict.solid_fraction, verdict.normal_stress, verdict.bulk_shear_rate,
      walls() ? fmt::format(", wall speed settled {}", speed_controller_.settled()) : "");
  return verdict.stationary() && (!walls() || speed_controller_.settled());
}

}  // namespace millflow::dem
