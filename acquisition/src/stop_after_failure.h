#pragma once
// After a run failed: stopping the instrument's stream and recording the interruption. The
// failure that got here is the one to report, so what these throw in turn is dropped.

#include <spdlog/spdlog.h>

#include <optional>
#include <string>

#include "mtcal/drivers/instrument.h"
#include "mtcal/error.h"
#include "mtcal/storage/store.h"

namespace mtcal::acquisition {

/// @return the stream's statistics when it stopped cleanly
inline std::optional<drivers::StreamStats> stopAfterFailure(drivers::Instrument& instrument) noexcept {
  try {
    return instrument.stopStream();
  } catch (...) {  // NOLINT(bugprone-empty-catch): the first failure is the one reported
    return std::nullopt;
  }
}

/// Records that a run stopped: `message` as an event of `level` and the status interrupted.
/// When the archive cannot take even that (its disk is full), the run is left as it was and
/// this process stops recording it: it reads interrupted (storage/run_owner.h) and resumes
/// like any.
inline void recordInterruption(storage::Store& store, storage::Id run_id, const std::string& level,
                               const std::string& message) noexcept {
  try {
    store.logEvent(run_id, level, message);
    store.setRunStatus(run_id, storage::run_status::kInterrupted);
  } catch (const Error& e) {
    spdlog::error("run {}: the interruption could not be recorded: {}", run_id, e.what());
    store.abandonRun(run_id);
  }
}

}  // namespace mtcal::acquisition
