#pragma once
// What the compensation tests share: a small hand-worked table and the message of a refusal.

#include <functional>
#include <string>

#include "mtcal/error.h"
#include "mtcal/processing/compensation.h"

namespace mtcal::processing::testing {

/// Three entries, bidirectional: the correction (um) up 0 / +2 / -2 and down +1 / +3 / -1 at
/// 0 / 10 / 20 mm.
inline CompensationTable threeEntries() {
  CompensationTable t;
  t.position = {0.0, 10.0, 20.0};
  t.up_um = {0.0, 2.0, -2.0};
  t.down_um = {1.0, 3.0, -1.0};
  return t;
}

/// The message of the InputError `f` throws; "no error" when it throws none.
inline std::string messageOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace mtcal::processing::testing
