#pragma once
// Import of linear positioning data exported by other software (CSV). A malformed row is
// reported with its line number and nothing is imported.
//
// Columns (header required, comma separated, '#' comment lines and blank lines skipped):
//   target_mm, direction (+/-, up/down, fwd/bwd), cycle, and measured_mm or deviation_um;
//   optional time_s, air_temp_c, air_pressure_pa, humidity_pct, material_temp_c;
//   any other column must be numeric and is stored as an auxiliary channel of the run.

#include <istream>
#include <string>
#include <vector>

#include "mtcal/processing/air_index.h"
#include "mtcal/storage/store.h"

namespace mtcal::acquisition {

struct LinearImportOptions {
  std::string axis = "X";
  std::string name;  ///< run name; the file name when empty
  std::string machine = "imported";
  /// measured_mm are raw (uncompensated) laser readings of the displacement from the datum:
  /// compensate them with the environment columns (air index, then NTC to 20 degC).
  bool raw = false;
  processing::AirIndexModel model = processing::AirIndexModel::kEdlen;
  double wavelength_nm = 632.991;
  double co2_ppm = 450.0;
  double expansion_per_k = 11.5e-6;
  double datum_mm = 0.0;  ///< with raw: machine position where the laser reading is zero
  std::string software_version = "unknown";
};

struct ParsedLinearCsv {
  std::vector<storage::TargetRecord> targets;
  std::vector<std::string> channel_names;
  std::vector<storage::ChannelRow> channel_rows;
};

/// Parses and validates the whole file. @throws InputError "SOURCE:LINE: column 'c': why"
ParsedLinearCsv parseLinearCsv(std::istream& in, const std::string& source, const LinearImportOptions& options);

/// Parses `path` and stores it as one run in one transaction. @return the run id
storage::Id importLinearCsv(storage::Store& store, const std::string& path, const LinearImportOptions& options);

}  // namespace mtcal::acquisition
