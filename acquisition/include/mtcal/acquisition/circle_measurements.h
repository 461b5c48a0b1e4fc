#pragma once
// The measurements of circular tests in and out of the store: the import of circle data
// exported by other software into a run, and a stored test's points for processing.

#include <Eigen/Core>
#include <istream>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "mtcal/acquisition/csv.h"
#include "mtcal/acquisition/store_when_needed.h"
#include "mtcal/processing/iso230_4.h"
#include "mtcal/processing/plane.h"
#include "mtcal/storage/store.h"

namespace mtcal::acquisition {

/// Converts the stored points of a circular test for processing.
std::vector<processing::CirclePoint> toCirclePoints(const std::vector<storage::CirclePointRecord>& records);

struct CircleImportOptions {
  double radius_mm = 0.0;
  processing::Plane plane = processing::Plane::kXY;
  /// The test's feed (the servo mismatch in ms scales with its inverse); none: not known, and
  /// kAssumedFeedMmPerMin is taken and said (feedAssumedNote).
  std::optional<double> feed_mm_per_min;
  /// Machine coordinates of the table ball, when known: a model can then predict the circle.
  std::optional<Eigen::Vector3d> centre_mm;
  std::string name;
  std::string machine = storage::kImportedMachine;
  std::string software_version = "unknown";
  /// The file's SHA-256 (lowercase hex), stored as the plan's imported_sha256: a later import of
  /// the same bytes is told (services). Empty: not stored.
  std::string source_sha256;
  CsvDialect csv;
};

constexpr double kAssumedFeedMmPerMin = 1000.0;

/// The options that do not depend on the file: a radius within 10 m, a feed within 1 000 000
/// mm/min, a centre within 100 m of the origin. @throws InputError naming the option
void checkCircleImportOptions(const CircleImportOptions& options);

/// Imports `angle_deg,direction,deviation_um` (optional time_s) into one run, in one
/// transaction. @throws InputError naming the line and column (a point given twice too);
/// nothing is stored then.
storage::Id importCircleCsv(const StoreWhenNeeded& store, const std::string& path, const CircleImportOptions& options);
/// The same of the file's bytes read already (`path` names it in messages and the plan).
storage::Id importCircleCsv(const StoreWhenNeeded& store, std::istream& in, const std::string& path,
                            const CircleImportOptions& options);

/// For a circle imported without its feed (its plan's "feed_assumed"): what was taken and what
/// it changes, for people; none otherwise.
std::optional<std::string> feedAssumedNote(const nlohmann::json& plan);

}  // namespace mtcal::acquisition
