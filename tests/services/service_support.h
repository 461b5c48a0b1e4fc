#pragma once
// What the service tests share: an observer that records what it is told, and an operator
// who answers from a script.

#include <string>
#include <vector>

#include "mtcal/error.h"
#include "mtcal/services/session.h"

namespace mtcal::testing {

struct RecordingObserver final : services::Observer {
  std::vector<services::Progress> progress;
  void onProgress(const services::Progress& p) override { progress.push_back(p); }
};

/// Confirms the first `answers` requests, then stops answering (as a closed stdin does).
struct ScriptedOperator final : services::Operator {
  explicit ScriptedOperator(std::size_t answers) : answers_(answers) {}
  std::vector<std::string> requests, told;
  void confirm(const std::string& request) override {
    requests.push_back(request);
    if (requests.size() > answers_) throw InputError("no answer from the operator at: " + request);
  }
  void tell(const std::string& text) override { told.push_back(text); }

 private:
  std::size_t answers_;
};

}  // namespace mtcal::testing
