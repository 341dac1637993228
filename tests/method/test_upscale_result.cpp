// A sweep point's upscale result (method/upscale_result.hpp): its JSON reads back to the same
// bytes, and a missing, ill-typed or inconsistent field is refused with its JSON pointer and
// owner.
#include <gtest/gtest.h>

#include <stdexcept>

#include "method/upscale_result.hpp"

namespace millflow::method {
namespace {

using nlohmann::json;

// A result with a distinct value in most fields, undefined figures as none, a media spectrum
// shift under one method only, and two bins.
UpscaleResult result() {
  const UpscaleFigures toe{.sites = 2,
                           .volume_m3 = 0.004,
                           .powder_power_w = 1.5,
                           .powder_power_share = 0.75,
                           .media_power_w = 9.0,
                           .cushioning = 0.8,
                           .cushioning_rate_factor = 0.9};
  UpscaleResult r{
      .cells = {.method = "cells",
                .totals = toe,
                .regions = {{.region = "toe",
                             .method = "cells",
                             .figures = toe,
                             .macro_dissipation_w = 12.0,
                             .cell_to_macro_power_ratio = 0.7}},
                .dominant_region = "toe"},
      .fill = 0.3,
      .speed_fraction = 0.75,
      .powder_load = 1.0,
      .average_task = "average-key",
      .sites_task = "sites-key",
      .mill = {.diameter_m = 0.2, .power_draw_w = 120.0},
      .powder_to_media_mass_ratio = 0.1,
      .spectra = {.bin_edges_j = {1e-6, 1e-4, 1e-2},
                  .powder_rate_per_s = {3.0, 1.0},
                  .media_rate_per_s = {5.0, 2.0},
                  .media_rate_no_powder_per_s = {4.0, 4.0}},
      .media_spectrum_shift =
          SpectrumShift{
              .threshold_j = 1e-4, .fraction_above = std::nullopt, .fraction_above_no_powder = 0.5},
      .left_out_cells = {{.site_id = "bulk-0", .powder_load = 0.0, .reason = "not steady"}},
      .sites = {{.site_id = "toe-0", .region = "toe", .coupling_ratio = 0.9},
                {.site_id = "bulk-0", .region = "bulk", .skipped = "no shear cell ran here"}},
      .coupling = {.sites = 1, .median_ratio = 0.9, .tolerance = 0.5, .within_tolerance = 1}};
  r.macro_anchored.figures = r.cells;
  r.macro_anchored.figures.method = "macro_anchored";
  r.macro_anchored.macro_dissipation_w = 12.0;
  r.sensitivity = {
      {.rule_set = "default",
       .regions = {{.region = "toe", .macro_dissipation_w = 12.0, .powder_power_w = 1.8}},
       .dominant_region = "toe",
       .toe_powder_power_share = 1.0}};
  return r;
}

std::string refusal(const json& document) {
  try {
    read_upscale_result(document, "upscale task u");
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "accepted";
}

TEST(UpscaleResult, JsonReadsBackToTheSameBytes) {
  const json written = result();
  EXPECT_EQ(written.at("sites").size(), 2u) << "the site rows, not the cells method's count";
  EXPECT_EQ(written.at("macro_anchored").at("sites").dump(), "2") << "counts stay integers";
  EXPECT_TRUE(written.at("power_draw_with_powder_w").is_null());
  EXPECT_TRUE(written.at("macro_anchored").at("media_spectrum_shift").is_null());
  EXPECT_TRUE(written.at("media_spectrum_shift").at("fraction_above").is_null());
  EXPECT_EQ(written.at("left_out_cells").at(0).at("counted"), false);
  const auto read = written.get<UpscaleResult>();
  EXPECT_EQ(read.cells.regions.at(0).figures.cushioning, 0.8);
  EXPECT_FALSE(read.cells.regions.at(0).figures.cushioning_se);
  EXPECT_EQ(read.sites.at(1).skipped, "no shear cell ran here");
  EXPECT_EQ(json(read).dump(), written.dump());
}

TEST(UpscaleResult, RefusesAFieldByItsPointer) {
  json missing = result();
  missing["macro_anchored"]["regions"][0].erase("powder_power_w");
  EXPECT_EQ(refusal(missing).rfind(
                "upscale task u: field /macro_anchored/regions/0/powder_power_w is missing", 0),
            0u)
      << refusal(missing);
  json flag = result();
  flag["left_out_cells"][0]["counted"] = "no";
  EXPECT_NE(refusal(flag).find("field /left_out_cells/0/counted is \"no\", not true or false"),
            std::string::npos)
      << refusal(flag);
  json short_spectrum = result();
  short_spectrum["spectra"]["media_rate_no_powder_per_s"] = {1.0};
  EXPECT_NE(refusal(short_spectrum)
                .find("field /spectra/media_rate_no_powder_per_s does not hold 2 bins"),
            std::string::npos)
      << refusal(short_spectrum);
}

}  // namespace
}  // namespace millflow::method
