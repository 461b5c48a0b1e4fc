// Cam grinding with geometric error compensation (mtcal grind compensate): a cam profile,
// a stored error model of an X + C grinder, the wheel's radius -> corrected X/C commands
// (CSV) and their part program.

#include <fmt/format.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "mtcal/acquisition/columns_csv.h"
#include "mtcal/acquisition/error_models.h"
#include "mtcal/error.h"
#include "mtcal/processing/grinding.h"

namespace mtcal::app {
namespace {

// x_mm,y_mm (a point list) or angle_deg,radius_mm (a lift table).
std::vector<Eigen::Vector2d> readProfile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot open file");
  std::string header;
  while (std::getline(in, header) && (header.empty() || header[0] == '#')) {
  }
  in.clear();
  in.seekg(0);
  if (header.find("angle_deg") != std::string::npos) {
    const auto c = acquisition::readColumnsCsv(in, path, {"angle_deg", "radius_mm"});
    return processing::polarProfile(c.at("angle_deg"), c.at("radius_mm"));
  }
  const auto c = acquisition::readColumnsCsv(in, path, {"x_mm", "y_mm"});
  std::vector<Eigen::Vector2d> out;
  for (std::size_t i = 0; i < c.at("x_mm").size(); ++i) out.emplace_back(c.at("x_mm")[i], c.at("y_mm")[i]);
  return out;
}

void writeText(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  if (!out) throw InputError(path + ": cannot write");
  out << text;
  if (!out.flush()) throw InputError(path + ": write failed");
}

}  // namespace

int grindCompensate(const Globals& g, const GrindOptions& options) {
  const auto profile = readProfile(options.profile_path);
  const auto path = processing::wheelCentrePath(profile, options.wheel_radius_mm, options.points);
  storage::Store store(g.db);
  const auto model = acquisition::loadModel(store, options.model_id);
  std::vector<Eigen::Vector2d> centres;
  for (const auto& w : path) centres.push_back(w.centre_mm);
  processing::CompensationOptions c;
  c.resolution_x_um = options.resolution_x_um;
  c.resolution_c_deg = options.resolution_c_deg;
  const auto commands = processing::compensateGrinding(
      model.kinematics(), [&model](const Eigen::VectorXd& q) { return model.errorsAt(q); }, centres, c);

  std::string csv =
      "point,profile_x_mm,profile_y_mm,centre_x_mm,centre_y_mm,x_ideal_mm,c_ideal_deg,x_mm,c_deg,iterations,"
      "error_ideal_um,error_um,error_z_um\n";
  double worst_ideal = 0.0, worst = 0.0, worst_z = 0.0;
  int iterations = 0;
  for (std::size_t i = 0; i < commands.size(); ++i) {
    const auto& k = commands[i];
    csv += fmt::format("{},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{},{:.4f},{:.4f},{:.4f}\n", i + 1,
                       path[i].profile_mm.x(), path[i].profile_mm.y(), path[i].centre_mm.x(), path[i].centre_mm.y(),
                       k.x_ideal_mm, k.c_ideal_deg, k.x_mm, k.c_deg, k.iterations, k.error_ideal_um, k.error_um,
                       k.error_z_um);
    worst_ideal = std::max(worst_ideal, k.error_ideal_um);
    worst = std::max(worst, k.error_um);
    worst_z = std::max(worst_z, std::abs(k.error_z_um));
    iterations = std::max(iterations, k.iterations);
  }
  if (!options.output_path.empty()) writeText(options.output_path, csv);
  if (!options.gcode_path.empty()) {
    writeText(options.gcode_path,
              processing::grindingGcode(commands, options.c_rpm,
                                        fmt::format("cam {} with model {}, wheel radius {} mm", options.profile_path,
                                                    options.model_id, options.wheel_radius_mm)));
  }
  const nlohmann::json summary{{"points", commands.size()},
                               {"model_id", options.model_id},
                               {"wheel_radius_mm", options.wheel_radius_mm},
                               {"max_error_ideal_um", worst_ideal},
                               {"max_error_um", worst},
                               {"max_error_z_um", worst_z},
                               {"max_iterations", iterations}};
  if (g.json) {
    *g.out << summary.dump() << "\n";
  } else {
    if (options.output_path.empty()) *g.out << csv << "\n";
    *g.out << fmt::format("{} wheel-centre points; wheel-centre error with the ideal commands up to {:.3f} um, with the "
                          "corrected ones up to {:.4f} um ({} iterations at most); along the camshaft {:.3f} um, which X "
                          "and C cannot correct\n",
                          commands.size(), worst_ideal, worst, iterations, worst_z);
  }
  return 0;
}

}  // namespace mtcal::app
