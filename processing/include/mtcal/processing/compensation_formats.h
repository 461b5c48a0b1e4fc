#pragma once
// Compensation tables as controllers load them: the file each controller reads, written from a
// table and read back the way the controller reads it. Text in, text out: no file I/O here.
// Formats and their sources: docs/compensation.md.

#include <string>
#include <string_view>
#include <vector>

#include "mtcal/processing/compensation.h"

namespace mtcal::processing {

/// What is written for one axis: the table file and the lines that activate it in the
/// controller's configuration (e.g. LinuxCNC's INI), with comments for the engineer.
struct ControllerFile {
  std::string text;
  std::string setup;  ///< the configuration lines to add; empty when the file carries them
  std::string extension;
};

/// The axis a table belongs to, as the controller names it.
struct AxisOfTable {
  std::string name = "X";  ///< the axis letter
  int index = 0;           ///< its number in the controller (LinuxCNC's joint, Siemens' AXn - 1, ...)
  /// The name the file is saved under, for the lines that name it (empty: the axis' name and
  /// the format's extension, e.g. X.comp).
  std::string file_name;

  std::string fileName(const std::string& extension) const { return file_name.empty() ? name + extension : file_name; }
};

/// A controller's table format and what it does with a table.
struct ControllerFormat {
  std::string name;         ///< as given to --controller
  std::string description;  ///< the file and the controller function, for people
  TableRules rules;         ///< how the controller applies the table
  std::size_t max_points = 0;
  double resolution_um = 0.0;  ///< values are rounded to this when the engineer does not say
  ControllerFile (*write)(const CompensationTable& table, const AxisOfTable& axis) = nullptr;
  /// Reads a file as the controller does; what the controller would silently drop (a line
  /// that ends a LinuxCNC table early) is an error here. @throws InputError "source: line N: why"
  CompensationTable (*read)(std::string_view text, const std::string& source) = nullptr;
};

/// The controller name of the volumetric compensation (a model's, every axis in one file:
/// volumetric_compensation.h). It is no axis' table format, so controllerFormat has it not.
inline constexpr const char* kIsgVolumetric = "isg-volumetric";

/// @throws InputError naming the controllers there are (and the volumetric one, for a model)
const ControllerFormat& controllerFormat(std::string_view name);
std::vector<std::string> controllerNames();

}  // namespace mtcal::processing
