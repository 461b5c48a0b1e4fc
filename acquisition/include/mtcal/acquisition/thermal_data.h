#pragma once
// Thermal monitoring data in and out of the store: the import of a CSV exported
// by other software (a data logger's), and a stored run as the thermal model reads it.
//
// CSV (header required, read as csv.h says: separator, decimal mark, units): an optional
// `time_s` column (else rows are `interval_s` apart), displacement columns (a length unit:
// names ending in `_um`, `drift [mm]`; or the one named by `target`, in um), spindle speed
// columns (`_rpm`), every other column a temperature in degC. An empty cell is a missing value (a
// sensor out), stored as missing, never as 0. A cell that is not a number, a temperature
// outside -60..300 degC or a time that does not increase is reported with its line and
// column, and nothing is imported.

#include <istream>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "mtcal/acquisition/csv.h"
#include "mtcal/acquisition/store_when_needed.h"
#include "mtcal/processing/thermal_model.h"
#include "mtcal/storage/store.h"

namespace mtcal::acquisition {

/// The time between an imported file's rows when neither a time column nor --interval-s gives it.
constexpr double kRowIntervalS = 60.0;
/// The longest time between rows: a day.
constexpr double kLongestRowIntervalS = 86400.0;

struct ThermalImportOptions {
  /// Between rows, for a file without a time column (kRowIntervalS when not given); refused
  /// beside one.
  std::optional<double> interval_s;
  std::string target;  ///< a displacement column (um) even without the _um suffix
  std::string name;    ///< run name; the file name when empty
  std::string machine = storage::kImportedMachine;
  std::string software_version = "unknown";
  /// The file's SHA-256 (lowercase hex), stored as the plan's imported_sha256: a later import of
  /// the same bytes is told (services). Empty: not stored.
  std::string source_sha256;
  CsvDialect csv;
};

struct ParsedThermalCsv {
  std::vector<storage::ThermalChannel> channels;
  std::vector<storage::ThermalSample> samples;
  std::vector<std::string> warnings;  ///< what the file's reading could not tell (a target beside a displacement)
};

/// Refuses an option wrong whatever the file (the interval between rows), before a file (or a
/// pipe) is read. @throws InputError naming the option
void checkThermalImportOptions(const ThermalImportOptions& options);

/// Parses and validates the whole file. @throws InputError "SOURCE:LINE: column 'c': why"
ParsedThermalCsv parseThermalCsv(std::istream& in, const std::string& source, const ThermalImportOptions& options);

struct ThermalCsvImport {
  storage::Id run_id = 0;
  std::vector<std::string> warnings;  ///< ParsedThermalCsv's
};

/// Parses the file's bytes (`path` names it in messages and the plan) and stores them as one
/// thermal run in one transaction.
ThermalCsvImport importThermalCsv(const StoreWhenNeeded& store, std::istream& in, const std::string& path,
                                  const ThermalImportOptions& options);

/// Writes a thermal run as the CSV import reads it (time_s, then every channel by name; a
/// missing value is an empty cell; the speed column ends in _rpm). @throws InputError
void writeThermalCsv(storage::Store& store, storage::Id run_id, std::ostream& out);

/// A thermal run's temperatures (and, with `with_speed`, its spindle speed channels: the
/// paper's machining parameter as one more input) and one displacement channel (`target`),
/// NaN where missing. @throws InputError when the run is not a thermal run or has no such
/// channel (naming those it has)
processing::ThermalData thermalDataOfRun(storage::Store& store, storage::Id run_id, const std::string& target,
                                         bool with_speed = false);

}  // namespace mtcal::acquisition
