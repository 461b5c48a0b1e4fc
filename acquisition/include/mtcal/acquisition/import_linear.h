#pragma once
// Import of linear runs exported by other software (CSV, read as csv.h says): positioning,
// straightness or angle along an axis, one error per file or several in one file, and whole
// campaigns (a manifest naming each file's axis, error, line and reflector). A malformed row is
// reported with its line number and nothing is imported.
//
// Columns (header required; names as csv.h matches them, units converted):
//   target_mm, direction (+/-, up/down, fwd/bwd), cycle, and the value:
//     deviation_um (positioning or straightness; or measured_mm for positioning), or
//     deviation_urad (pitch, yaw, roll: "deviation [arcsec]", "[mm/m]" ... are converted), or
//     one column per error of the axis named by it: EXX_um, EYX_um, EZX_um, EAX_urad, EBX_urad,
//     ECX_urad ("EBX [arcsec]" ...), each a run of its own;
//   optional time_s, air_temp_c, air_pressure_pa, humidity_pct, material_temp_c;
//   any other column must be numeric and is stored as an auxiliary channel of the run(s).

#include <array>
#include <istream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "mtcal/acquisition/csv.h"
#include "mtcal/acquisition/linear_plan.h"
#include "mtcal/acquisition/store_when_needed.h"
#include "mtcal/processing/air_index.h"
#include "mtcal/storage/store.h"

namespace mtcal::acquisition {

struct LinearImportOptions {
  std::string axis = "X";
  /// The error the value column measures (EXX..ECX for axis X); empty: positioning, or the
  /// error columns' names.
  std::string measures;
  /// The unit of a value column whose header has none ("um", "arcsec", "mm/m" ...).
  std::string value_unit;
  std::map<std::string, double> line_position_mm;            ///< the other axes on the measured line (0 if not named)
  std::optional<std::array<double, 3>> reflector_offset_mm;  ///< the optic from the tool point
  std::string name;  ///< run name; the file name when empty (with the error for several)
  std::string machine = storage::kImportedMachine;
  /// measured_mm are raw (uncompensated) laser readings of the displacement from the datum:
  /// compensate them with the environment columns (air index, then NTC to 20 degC).
  bool raw = false;
  processing::AirIndexModel model = processing::AirIndexModel::kEdlen;
  double wavelength_nm = 632.991;
  double co2_ppm = 450.0;
  double expansion_per_k = 11.5e-6;
  double datum_mm = 0.0;  ///< with raw: machine position where the laser reading is zero
  std::string software_version = "unknown";
  /// The file's SHA-256 (lowercase hex), stored as the plan's imported_sha256: a later import of
  /// the same bytes is told (services). Empty: not stored.
  std::string source_sha256;
  CsvDialect csv;
};

/// One measured error of a file.
struct ParsedLinearRun {
  std::string measures;    ///< EXX ...
  std::string value_unit;  ///< um, or urad for an angle
  std::vector<storage::TargetRecord> targets;
  std::vector<storage::ChannelRow> channel_rows;  ///< per target, the values of channel_names
};

struct ParsedLinearCsv {
  std::vector<ParsedLinearRun> runs;  ///< in the order EXX, EYX, EZX, EAX, EBX, ECX
  std::vector<std::string> channel_names;
  /// What is imported as given but looks wrong ("SOURCE:LINE: why"): times that cannot be one
  /// clock's (a pass whose time goes back, two passes beginning together, a cycle beginning no
  /// later than the one before it), one time on every row.
  std::vector<std::string> warnings;
};

/// The options that do not depend on the file (the axis, the error measured, the line's setup,
/// the unit, the air's with --raw), checked before it is read; the line's setup as a plan has it.
/// @throws InputError "SOURCE: the error measured: why" (SOURCE: what gave the options)
LinearPlan checkLinearImportOptions(const LinearImportOptions& options, const std::string& source);

/// Parses and validates the whole file. @throws InputError "SOURCE:LINE: column 'c': why"
ParsedLinearCsv parseLinearCsv(std::istream& in, const std::string& source, const LinearImportOptions& options);

/// What importLinearCsv stored: one run per error of the file.
struct LinearImport {
  std::vector<storage::Id> run_ids;
  std::vector<std::string> measures;  ///< per run, the error it measures (EXX ...)
  std::vector<std::size_t> readings;  ///< per run (a column's cells that hold a value)
  std::vector<std::string> warnings;  ///< the parse's (ParsedLinearCsv::warnings)
  nlohmann::json document() const {
    return {{"schema_version", 1},  {"run_id", run_ids.front()}, {"run_ids", run_ids},
            {"measures", measures}, {"readings", readings},      {"warnings", warnings}};
  }
};

/// Parses `path` and stores its runs in a new campaign "import FILE" (one transaction; the
/// store asked for once the file is read and sound).
LinearImport importLinearCsv(const StoreWhenNeeded& store, const std::string& path, const LinearImportOptions& options);
/// The same of the file's bytes read already (`path` names it in messages and the plan).
LinearImport importLinearCsv(const StoreWhenNeeded& store, std::istream& in, const std::string& path,
                             const LinearImportOptions& options);

/// A whole campaign of linear runs from other software, as one campaign. The manifest (JSON or
/// CSV) names per run: file (relative to the manifest), axis, measures, line position,
/// reflector offset and the value's unit when the file's header has none; docs/import.md.
struct CampaignImport {
  storage::Id campaign_id = 0;
  std::vector<storage::Id> run_ids;
  std::vector<std::string> warnings;  ///< every file's (ParsedLinearCsv::warnings)
};
struct CampaignImportOptions {
  std::string name;     ///< campaign name; the manifest's, else the file name
  std::string machine;  ///< the manifest's when empty, else storage::kImportedMachine
  std::string software_version = "unknown";
  CsvDialect csv;  ///< for the manifest and every file
};
/// @throws InputError naming the manifest line or entry, or the run file's line; nothing is stored
CampaignImport importLinearCampaign(const StoreWhenNeeded& store, const std::string& manifest_path,
                                    const CampaignImportOptions& options);

}  // namespace mtcal::acquisition
