#pragma once
// Plans and what surrounds them: the part program of any plan, and the instruments a
// session can reach.

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "mtcal/drivers/registry.h"
#include "mtcal/services/workshop.h"

namespace mtcal::services {

/// The NC program of a plan, by the plan's type (linear, circle, thermal, gantry).
struct PartProgram {
  std::string type;
  std::string program;
  std::size_t targets = 0;  ///< positions the program stops at for a measurement (linear, gantry)
  /// The program written to `file` (named), or, when empty, the program's text itself.
  nlohmann::json document(const std::string& file) const;
};
/// `machine_file`: a gantry plan's machine (its kinematics place the holes).
/// @throws InputError naming the file and key
PartProgram partProgram(const std::string& plan_path, const std::string& machine_file);

/// Every instrument the built-in drivers find, and the simulated ones.
std::vector<drivers::ScanResult> scanDevices(const SimulationOptions& simulation);

}  // namespace mtcal::services
