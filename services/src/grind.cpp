#include "mtcal/services/grind.h"

#include <fmt/format.h>

#include <cmath>
#include <fstream>

#include "mtcal/acquisition/csv.h"
#include "mtcal/acquisition/error_models.h"
#include "mtcal/error.h"
#include "mtcal/services/model.h"
#include "mtcal/services/workshop.h"

namespace mtcal::services {
namespace {

// x_mm,y_mm (a point list) or angle_deg,radius_mm (a lift table).
std::vector<Eigen::Vector2d> readProfile(const std::string& path) {
  std::ifstream in = acquisition::openInputFile(path);
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

processing::BallbarSetup readLayout(const std::string& path) {
  const auto j = readJsonFile(path);
  if (!j.is_object()) throw InputError(path + ": not a JSON object");
  auto vec = [&](const nlohmann::json& v, const std::string& where) {
    if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() || !v[2].is_number()) {
      throw InputError(path + ": " + where + ": must be [x, y, z] in mm");
    }
    return Eigen::Vector3d(v[0].get<double>(), v[1].get<double>(), v[2].get<double>());
  };
  processing::BallbarSetup s;
  if (!j.contains("coordinate") || !j["coordinate"].is_string())
    throw InputError(path + ": coordinate: the axis moved, e.g. \"c\"");
  s.coordinate = j["coordinate"].get<std::string>();
  if (!j.contains("pairs") || !j["pairs"].is_array() || j["pairs"].empty()) {
    throw InputError(path + ": pairs: a list of {\"tool_ball_mm\": [x, y, z], \"work_ball_mm\": [x, y, z]}");
  }
  for (std::size_t i = 0; i < j["pairs"].size(); ++i) {
    const auto& p = j["pairs"][i];
    const std::string where = "pairs[" + std::to_string(i) + "]";
    if (!p.is_object() || !p.contains("tool_ball_mm") || !p.contains("work_ball_mm")) {
      throw InputError(path + ": " + where + ": needs tool_ball_mm and work_ball_mm");
    }
    s.pairs.push_back(
        {vec(p["tool_ball_mm"], where + ".tool_ball_mm"), vec(p["work_ball_mm"], where + ".work_ball_mm")});
  }
  s.unknown_tool_ball_offset = j.value("unknown_tool_ball_offset", false);
  return s;
}

}  // namespace

nlohmann::json GrindCompensation::document() const {
  return {{"schema_version", 1},
          {"points", commands.size()},
          {"model_id", model_id},
          {"wheel_radius_mm", wheel_radius_mm},
          {"max_error_ideal_um", max_error_ideal_um},
          {"max_error_um", max_error_um},
          {"max_error_z_um", max_error_z_um},
          {"max_iterations", max_iterations}};
}

std::string GrindCompensation::csv() const {
  std::string csv =
      "point,profile_x_mm,profile_y_mm,centre_x_mm,centre_y_mm,x_ideal_mm,c_ideal_deg,x_mm,c_deg,iterations,"
      "error_ideal_um,error_um,error_z_um\n";
  for (std::size_t i = 0; i < commands.size(); ++i) {
    const auto& k = commands[i];
    csv += fmt::format("{},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{},{:.4f},{:.4f},{:.4f}\n", i + 1,
                       path[i].profile_mm.x(), path[i].profile_mm.y(), path[i].centre_mm.x(), path[i].centre_mm.y(),
                       k.x_ideal_mm, k.c_ideal_deg, k.x_mm, k.c_deg, k.iterations, k.error_ideal_um, k.error_um,
                       k.error_z_um);
  }
  return csv;
}

GrindCompensation grindCompensate(Session& session, const GrindRequest& request) {
  GrindCompensation r;
  r.model_id = request.model_id;
  r.wheel_radius_mm = request.wheel_radius_mm;
  r.path = processing::wheelCentrePath(readProfile(request.profile_path), request.wheel_radius_mm, request.points);
  const auto model = acquisition::loadModel(session.store(), request.model_id);
  std::vector<Eigen::Vector2d> centres;
  for (const auto& w : r.path) centres.push_back(w.centre_mm);
  processing::CompensationOptions c;
  c.resolution_x_um = request.resolution_x_um;
  c.resolution_c_deg = request.resolution_c_deg;
  r.commands = processing::compensateGrinding(
      model.kinematics(), [&model](const Eigen::VectorXd& q) { return model.errorsAt(q); }, centres, c);
  for (const auto& k : r.commands) {
    r.max_error_ideal_um = std::max(r.max_error_ideal_um, k.error_ideal_um);
    r.max_error_um = std::max(r.max_error_um, k.error_um);
    r.max_error_z_um = std::max(r.max_error_z_um, std::abs(k.error_z_um));
    r.max_iterations = std::max(r.max_iterations, k.iterations);
  }
  // Both made, then written together: a program that cannot be made or written leaves no command list.
  const std::string program =
      request.gcode_path.empty()
          ? std::string()
          : processing::grindingGcode(r.commands, request.c_rpm,
                                      fmt::format("cam {} with model {}, wheel radius {} mm", request.profile_path,
                                                  request.model_id, request.wheel_radius_mm));
  std::vector<std::pair<std::string, std::string>> files;
  if (!request.output_path.empty()) files.emplace_back(request.output_path, r.csv());
  if (!request.gcode_path.empty()) files.emplace_back(request.gcode_path, program);
  writeTextFiles(files);
  return r;
}

nlohmann::json GrindIdentification::document() const {
  const auto& id = result;
  nlohmann::json values = nlohmann::json::array();
  for (Eigen::Index j = 0; j < id.values.rows(); ++j) {
    nlohmann::json row{{"position", id.coordinate[static_cast<std::size_t>(j)]}};
    for (std::size_t t = 0; t < id.terms.size(); ++t) row[id.terms[t]] = id.values(j, static_cast<Eigen::Index>(t));
    values.push_back(row);
  }
  nlohmann::json out{{"schema_version", 1},
                     {"coordinate", coordinate},
                     {"terms", id.terms},
                     {"not_determined", id.not_determined},
                     {"values", values},
                     {"rms_residual_um", id.rms_residual_um},
                     {"condition_number", id.condition_number}};
  if (id.tool_ball_offset_um) out["tool_ball_offset_um"] = {id.tool_ball_offset_um->x(), id.tool_ball_offset_um->y()};
  return out;
}

GrindIdentification grindIdentify(const std::string& readings_path, const std::string& machine_path,
                                  const std::string& layout_path) {
  const auto machine = readMachine(machine_path);
  const auto setup = readLayout(layout_path);
  std::ifstream in = acquisition::openInputFile(readings_path);
  const auto table = acquisition::readColumnTable(in, readings_path, {"position", "pair", "delta_length_um"}, {}, {});
  // Positions in file order, each with one length change per pair.
  std::vector<processing::BallbarReadings> readings;
  const auto& position = table.numbers.at("position");
  const auto& pair = table.numbers.at("pair");
  const auto& delta = table.numbers.at("delta_length_um");
  for (std::size_t i = 0; i < position.size(); ++i) {
    const auto k = static_cast<long>(pair[i]);
    if (k < 1 || k > static_cast<long>(setup.pairs.size()) || static_cast<double>(k) != pair[i]) {
      throw InputError(fmt::format("{}:{}: column 'pair': {} is not a pair of the layout (1..{})", readings_path,
                                   table.lines[i], pair[i], setup.pairs.size()));
    }
    if (readings.empty() || readings.back().coordinate != position[i]) {
      readings.push_back({position[i], std::vector<double>(setup.pairs.size(), std::nan(""))});
    }
    readings.back().delta_length_um[static_cast<std::size_t>(k - 1)] = delta[i];
  }
  for (const auto& r : readings) {
    for (std::size_t k = 0; k < r.delta_length_um.size(); ++k) {
      if (std::isnan(r.delta_length_um[k])) {
        throw InputError(
            fmt::format("{}: position {}: no length change for pair {}", readings_path, r.coordinate, k + 1));
      }
    }
  }
  return {setup.coordinate, setup.pairs.size(), processing::identifyFromBallbar(machine.model, setup, readings)};
}

}  // namespace mtcal::services
