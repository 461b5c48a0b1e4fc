#include "report.h"

#include <fmt/format.h>

namespace mtcal::app {

namespace {
std::string cell(const std::optional<double>& v, int width = 8) {
  return v ? fmt::format("{:>{}.2f}", *v, width) : fmt::format("{:>{}}", "-", width);
}

void printIso230Table(std::ostream& out, const processing::Iso230Result& r) {
  out << fmt::format("{:>10} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8}\n", "target_mm", "x_up", "x_down", "s_up", "s_down",
                     "B_i", "R_i");
  out << fmt::format("{:>10} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8}\n", "", "um", "um", "um", "um", "um", "um");
  for (const auto& p : r.positions) {
    out << fmt::format("{:>10.3f} {} {} {} {} {} {}\n", p.target_mm, cell(p.mean_up_um), cell(p.mean_down_um),
                       cell(p.s_up_um), cell(p.s_down_um), cell(p.reversal_um), cell(p.repeatability_um));
  }
  out << "\nISO 230-2:2014 axis results (um)\n";
  // The figures with ISO 230-2:2014's names, as analyze linear and compare give them.
  for (const auto& f : processing::evaluateStandard(r, "iso230-2:2014").figures)
    out << fmt::format("  {:<64} {:<7} {:>8.2f}\n", f.name, f.symbol, f.value_um);
}

}  // namespace

void printIso230(std::ostream& out, const services::Iso230Analysis& a) {
  printIso230Table(out, a.result);
  for (const auto& w : a.warnings) out << fmt::format("  warning: {}\n", w);
}

void ProgressBar::update(std::size_t done, std::size_t total, const std::string& detail) {
  if (total == 0) return;
  if (terminal_) {
    constexpr int kWidth = 30;
    const int filled = static_cast<int>(kWidth * done / total);
    err_ << fmt::format("\r[{}{}] {:>4}/{:<4} {}", std::string(filled, '#'), std::string(kWidth - filled, '.'), done,
                        total, detail)
         << "\x1b[K" << std::flush;
    drawn_ = true;
    return;
  }
  const int decile = static_cast<int>(10 * done / total);
  if (decile != last_decile_) {
    last_decile_ = decile;
    // A line each tenth of the way, with the share actually done (1 of 3: 33 %, not 30 %).
    err_ << fmt::format("progress {:>3}% ({}/{}) {}\n", 100 * done / total, done, total, detail) << std::flush;
  }
}

void ProgressBar::finish() {
  if (terminal_ && drawn_) err_ << "\n";
  drawn_ = false;
}

}  // namespace mtcal::app
