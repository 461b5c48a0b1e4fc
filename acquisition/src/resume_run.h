#pragma once
// Resuming a stored run: the checks and the record every kind shares.

#include <fmt/format.h>

#include <string>
#include <string_view>

#include "mtcal/error.h"
#include "mtcal/storage/store.h"

namespace mtcal::acquisition {

/// The run to resume, refused when it is not of `kind` (`kind_in_words` names it in the message).
inline storage::RunInfo runToResume(storage::Store& store, storage::Id run_id, std::string_view kind,
                                    std::string_view kind_in_words) {
  auto info = store.run(run_id);
  if (info.kind != kind)
    throw InputError(
        fmt::format("run {} is {}, not a {}", run_id, storage::run_kind::aRunOf(info.kind), kind_in_words));
  return info;
}

/// Takes the run over for this process (refused while its owner lives, storage/run_owner.h) and
/// records what it held already (`measured_before`, e.g. "4 of 12 targets").
inline void takeOverRun(storage::Store& store, storage::Id run_id, const std::string& measured_before) {
  store.claimRun(run_id);
  store.logEvent(run_id, "info", measured_before + " were measured before");
}

}  // namespace mtcal::acquisition
