#include "cli_session.h"

#include <fmt/format.h>

#include <cmath>
#include <string>

#include "mtcal/error.h"

namespace mtcal::app {

void CliObserver::onProgress(const services::Progress& p) {
  if (!draw_) return;
  std::string detail = p.what;
  if (p.eta_s && p.done < p.total) {
    const auto s = static_cast<long>(std::lround(*p.eta_s));
    detail += s >= 60 ? fmt::format("  {} min {:02} s left", s / 60, s % 60) : fmt::format("  {} s left", s);
  }
  bar_.update(p.done, p.total, detail);
}

void CliObserver::onMessage(const std::string& level, const std::string& text) {
  bar_.finish();
  err_ << (level == "info" ? "" : level + ": ") << text << "\n" << std::flush;
}

void CliOperator::confirm(const std::string& request) {
  err_ << request << " [Enter] " << std::flush;
  std::string answer;
  if (!in_ || !std::getline(*in_, answer)) {
    throw InputError("no answer from the operator: no operator input (standard input closed) at: " + request);
  }
}

void CliOperator::tell(const std::string& text) { err_ << text << "\n" << std::flush; }

CliSession::CliSession(const Globals& g)
    : observer(*g.err, g.terminal, !g.json && !g.quiet),
      person(*g.err, g.in),
      session(services::SessionOptions{g.db, g.operator_name, &observer, &person, g.stop}) {}

}  // namespace mtcal::app
