// mtcal est: straightness by error separation (two-probe, three-probe, frequency domain) from
// probe readings in a CSV file.

#include <fmt/format.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "mtcal/acquisition/columns_csv.h"
#include "mtcal/error.h"
#include "mtcal/processing/est.h"

namespace mtcal::app {

int estimateStraightness(const Globals& g, const EstOptions& options) {
  std::ifstream in(options.csv_path);
  if (!in) throw InputError(options.csv_path + ": cannot open file");
  const bool three = options.method == "three-probe";
  std::vector<std::string> required{"x_mm", "v1_um", "v2_um"};
  if (three) required.push_back("v3_um");
  const auto columns = acquisition::readColumnsCsv(in, options.csv_path, required);
  const auto& x = columns.at("x_mm");
  const auto& v1 = columns.at("v1_um");
  const auto& v2 = columns.at("v2_um");
  processing::EstResult r;
  if (options.method == "two-probe") {
    r = processing::separateTwoProbe(x, v1, v2, options.spacing_mm,
                                     options.start == "second-point" ? processing::EstStart::kSecondPointOnly
                                                                     : processing::EstStart::kCarriageAtRest);
  } else if (three) {
    r = processing::separateThreeProbe(x, v1, v2, columns.at("v3_um"), options.spacing_mm);
  } else {
    r = processing::separateFrequency(x, v1, v2, options.spacing_mm);
  }
  const auto s = processing::evaluateStraightness(r.x_mm, r.profile_um);
  if (g.json) {
    nlohmann::json out = {{"method", options.method},
                          {"spacing_mm", options.spacing_mm},
                          {"x_mm", r.x_mm},
                          {"straightness_um", r.profile_um},
                          {"carriage_um", r.carriage_um},
                          {"straightness_lsq_um", s.least_squares_um},
                          {"straightness_minzone_um", s.min_zone_um},
                          {"straightness_endpoint_um", s.end_point_um},
                          {"lost_wavelengths_mm", r.lost_wavelengths_mm}};
    *g.out << out.dump() << "\n";
    return 0;
  }
  *g.out << fmt::format("{} separation, probe spacing {} mm, {} points\n\n", options.method, options.spacing_mm, x.size());
  *g.out << "      x_mm   profile_um  carriage_um\n";
  for (std::size_t k = 0; k < r.x_mm.size(); ++k) {
    *g.out << fmt::format("{:>10.3f} {:>12.3f} {:>12}\n", r.x_mm[k], r.profile_um[k],
                          k < r.carriage_um.size() ? fmt::format("{:.3f}", r.carriage_um[k]) : "-");
  }
  *g.out << fmt::format("\nstraightness (um): least squares {:.3f}, minimum zone {:.3f}, end points {:.3f}\n",
                        s.least_squares_um, s.min_zone_um, s.end_point_um);
  if (!r.lost_wavelengths_mm.empty()) {
    *g.out << fmt::format("harmonics lost by the frequency method: wavelengths {} mm\n",
                          fmt::join(r.lost_wavelengths_mm, ", "));
  }
  return 0;
}

}  // namespace mtcal::app
