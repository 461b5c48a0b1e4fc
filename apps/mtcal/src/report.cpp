#include "report.h"

#include <fmt/format.h>

namespace mtcal::app {

namespace {
std::string cell(const std::optional<double>& v, int width = 8) {
  return v ? fmt::format("{:>{}.2f}", *v, width) : fmt::format("{:>{}}", "-", width);
}
}  // namespace

void printIso230Table(std::ostream& out, const processing::Iso230Result& r) {
  out << fmt::format("{:>10} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8}\n", "target_mm", "x_up", "x_down", "s_up", "s_down",
                     "B_i", "R_i");
  out << fmt::format("{:>10} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8}\n", "", "um", "um", "um", "um", "um", "um");
  for (const auto& p : r.positions) {
    out << fmt::format("{:>10.3f} {} {} {} {} {} {}\n", p.target_mm, cell(p.mean_up_um), cell(p.mean_down_um),
                       cell(p.s_up_um), cell(p.s_down_um), cell(p.reversal_um), cell(p.repeatability_um));
  }
  out << "\nISO 230-2:2014 axis results (um)\n";
  auto line = [&](const char* label, const char* symbol, const std::optional<double>& v) {
    out << fmt::format("  {:<48} {:<6} {}\n", label, symbol, cell(v));
  };
  line("reversal value", "B", r.B_um);
  line("mean reversal value", "B_mean", r.B_mean_um);
  line("unidirectional repeatability, up / down", "R_up", r.R_up_um);
  line("", "R_down", r.R_down_um);
  line("bidirectional repeatability", "R", r.R_um);
  line("unidirectional systematic deviation, up / down", "E_up", r.E_up_um);
  line("", "E_down", r.E_down_um);
  line("bidirectional systematic positional deviation", "E", r.E_um);
  line("range of mean bidirectional deviation", "M", r.M_um);
  line("unidirectional accuracy, up / down", "A_up", r.A_up_um);
  line("", "A_down", r.A_down_um);
  line("bidirectional accuracy", "A", r.A_um);
  if (r.min_cycles < 5) {
    out << fmt::format("  warning: only {} cycle(s) at some target; ISO 230-2 asks for at least 5\n", r.min_cycles);
  }
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
    err_ << fmt::format("progress {:>3}% ({}/{}) {}\n", decile * 10, done, total, detail) << std::flush;
  }
}

void ProgressBar::finish() {
  if (terminal_ && drawn_) err_ << "\n";
  drawn_ = false;
}

}  // namespace mtcal::app
