#pragma once
// Presentation of results as text: aligned tables and the progress bar.

#include <nlohmann/json.hpp>
#include <ostream>
#include <vector>

#include "mtcal/services/linear.h"

namespace mtcal::app {

/// Every target's means and spreads, the standard's figures, and what they stand on
/// (Iso230Analysis::warnings).
void printIso230(std::ostream& out, const services::Iso230Analysis& analysis);

/// Text progress bar on one line (\r) for a terminal, a line per 10 % otherwise.
class ProgressBar {
 public:
  ProgressBar(std::ostream& err, bool terminal) : err_(err), terminal_(terminal) {}
  void update(std::size_t done, std::size_t total, const std::string& detail);
  void finish();

 private:
  std::ostream& err_;
  bool terminal_;
  int last_decile_ = -1;
  bool drawn_ = false;
};

}  // namespace mtcal::app
