#pragma once
// The command line's side of a services session: progress drawn on stderr, the operator
// asked on stderr and answering on stdin.

#include <istream>
#include <ostream>

#include "commands.h"
#include "mtcal/services/session.h"
#include "report.h"

namespace mtcal::app {

/// Draws a long operation's progress on stderr (text output only: --json keeps stderr for
/// messages) and prints its messages there.
class CliObserver final : public services::Observer {
 public:
  CliObserver(std::ostream& err, bool terminal, bool draw) : err_(err), bar_(err, terminal), draw_(draw) {}
  ~CliObserver() override { bar_.finish(); }
  void onProgress(const services::Progress& p) override;
  void onMessage(const std::string& level, const std::string& text) override;
  /// Ends the bar's line (before printing results).
  void finish() { bar_.finish(); }

 private:
  std::ostream& err_;
  ProgressBar bar_;
  bool draw_;
};

/// The operator at the terminal: requests on stderr, confirmed with Enter on stdin.
class CliOperator final : public services::Operator {
 public:
  CliOperator(std::ostream& err, std::istream* in) : err_(err), in_(in) {}
  void confirm(const std::string& request) override;
  void tell(const std::string& text) override;

 private:
  std::ostream& err_;
  std::istream* in_;
};

/// A session on the command's database with the terminal's observer and operator.
struct CliSession {
  explicit CliSession(const Globals& g);
  CliObserver observer;
  CliOperator person;
  services::Session session;
};

}  // namespace mtcal::app
