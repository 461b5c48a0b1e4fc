#pragma once
// Stopping an instrument's stream after a run failed: the failure that got here is the one to
// report, so what stopping throws in turn is dropped.

#include <optional>

#include "mtcal/drivers/instrument.h"

namespace mtcal::acquisition {

/// @return the stream's statistics when it stopped cleanly
inline std::optional<drivers::StreamStats> stopAfterFailure(drivers::Instrument& instrument) noexcept {
  try {
    return instrument.stopStream();
  } catch (...) {  // NOLINT(bugprone-empty-catch): the first failure is the one reported
    return std::nullopt;
  }
}

}  // namespace mtcal::acquisition
