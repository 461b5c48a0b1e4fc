#pragma once
// Cam grinding on an X + C grinder (docs/grinding.md): corrected X/C commands from a cam
// profile and a stored error model, and one axis' motion errors identified from ballbar
// length changes.

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "mtcal/processing/ballbar_identification.h"
#include "mtcal/processing/grinding.h"
#include "mtcal/services/session.h"

namespace mtcal::services {

struct GrindRequest {
  std::string profile_path;  ///< x_mm,y_mm or angle_deg,radius_mm
  storage::Id model_id = 0;  ///< a stored error model of an X + C grinder
  double wheel_radius_mm = 0.0;
  int points = 720;  ///< wheel-centre points along the profile
  double resolution_x_um = 0.1, resolution_c_deg = 0.0001;
  std::string output_path;  ///< the command list (CSV), when given
  std::string gcode_path;   ///< the part program, when given
  double c_rpm = 10.0;
};

struct GrindCompensation {
  storage::Id model_id = 0;
  double wheel_radius_mm = 0.0;
  std::vector<processing::WheelPathPoint> path;
  std::vector<processing::GrindCommand> commands;
  double max_error_ideal_um = 0.0, max_error_um = 0.0, max_error_z_um = 0.0;
  int max_iterations = 0;
  nlohmann::json document() const;
  /// One row per wheel-centre point: profile, centre, ideal and corrected commands, errors.
  std::string csv() const;
};
/// Computes the corrected commands and writes the files asked for.
/// @throws InputError naming the file and why
GrindCompensation grindCompensate(Session& session, const GrindRequest& request);

struct GrindIdentification {
  std::string coordinate;
  std::size_t placements = 0;
  processing::BallbarIdentification result;
  nlohmann::json document() const;
};
/// `readings_path` CSV position,pair,delta_length_um; `layout_path` JSON: coordinate, pairs of
/// tool-side and workpiece-side balls. @throws InputError naming the file, line and column
GrindIdentification grindIdentify(const std::string& readings_path, const std::string& machine_path,
                                  const std::string& layout_path);

}  // namespace mtcal::services
