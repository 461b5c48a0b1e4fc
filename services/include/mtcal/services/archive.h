#pragma once
// What the archive holds: its runs listed, one run shown whole.

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "mtcal/services/session.h"

namespace mtcal::services {

/// Why a stale run (status running, its process gone) reads interrupted; empty for others.
std::string staleNote(const storage::RunInfo& run);

/// A run as `mtcal runs --json` lists it.
nlohmann::json runDocument(const storage::RunInfo& run);

/// The list `mtcal runs --json` prints: {"schema_version", "runs": [...]}.
nlohmann::json runListDocument(const std::vector<storage::RunInfo>& runs);

/// Every run, oldest first.
std::vector<storage::RunInfo> listRuns(Session& session);

/// One run whole: what `mtcal show` tells.
struct RunDetail {
  storage::RunInfo run;
  std::vector<storage::TargetRecord> targets;
  std::vector<storage::Store::Event> events;
  std::vector<storage::RunInstrument> instruments;  ///< every instrument that measured, the main one first
  std::vector<std::string> channels;                ///< auxiliary channels of imported data
  std::int64_t raw_samples = 0;                     ///< acquired runs
  std::int64_t tracker_points = 0;                  ///< gantry runs
  std::int64_t thermal_samples = 0;                 ///< thermal runs
  std::vector<storage::ThermalChannel> thermal_channels;
  std::vector<storage::Store::Result> results;  ///< stored analyses, oldest first
  nlohmann::json document() const;
};
/// @throws InputError when there is no such run
RunDetail showRun(Session& session, storage::Id run_id);

}  // namespace mtcal::services
