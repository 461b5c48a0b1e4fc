#include "mtcal/processing/positioning_standards.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <functional>

#include "mtcal/error.h"

namespace mtcal::processing {
namespace {

/// What a figure is made of: a per-target quantity, its largest and smallest over the targets.
struct Range {
  double high = -INFINITY, low = INFINITY;
  void add(double upper, double lower) { high = std::max(high, upper), low = std::min(low, lower); }
  double span() const { return high - low; }
};

void iso230_2(const Iso230Result& r, StandardEvaluation& e) {
  const auto add = [&](const char* symbol, const char* name, const std::optional<double>& v) {
    if (v) e.figures.push_back({symbol, name, *v});
  };
  add("E", "bidirectional systematic positioning error", r.E_um);
  add("E up", "unidirectional systematic positioning error, positive approach", r.E_up_um);
  add("E down", "unidirectional systematic positioning error, negative approach", r.E_down_um);
  add("M", "mean bidirectional positioning error", r.M_um);
  add("R", "bidirectional repeatability of positioning", r.R_um);
  add("R up", "unidirectional repeatability of positioning, positive approach", r.R_up_um);
  add("R down", "unidirectional repeatability of positioning, negative approach", r.R_down_um);
  add("B", "reversal error", r.B_um);
  add("B mean", "mean reversal error", r.B_mean_um);
  add("A", "bidirectional accuracy of positioning", r.A_um);
  add("A up", "unidirectional accuracy of positioning, positive approach", r.A_up_um);
  add("A down", "unidirectional accuracy of positioning, negative approach", r.A_down_um);
}

/// The per-target values both VDI 3441 and ASME B5.54 need: both directions' means and s.
struct Bidirectional {
  double up, down, s_up, s_down;
};

std::vector<Bidirectional> bothDirections(const Iso230Result& r, std::string_view title) {
  std::vector<Bidirectional> targets;
  for (const auto& p : r.positions) {
    if (!p.mean_up_um || !p.mean_down_um || !p.s_up_um || !p.s_down_um) {
      throw InputError(fmt::format("{} needs both approach directions with at least 2 cycles: target {:g} mm has not",
                                   title, p.target_mm));
    }
    targets.push_back({*p.mean_up_um, *p.mean_down_um, *p.s_up_um, *p.s_down_um});
  }
  return targets;
}

/// VDI/DGQ 3441 (as described in secondary sources): at each target j the mean position
/// deviation x_j (the mean of both directions), the reversal span U_j = |x_j up - x_j down| and
/// the positional scatter Ps_j = 6 s_j with s_j the mean of both directions' s; Pa is the range
/// of x_j, and the positional uncertainty P the range of x_j +- (U_j + Ps_j) / 2.
void vdi3441(const Iso230Result& r, StandardEvaluation& e) {
  Range mean, uncertainty;
  double u_max = 0.0, u_sum = 0.0, ps_max = 0.0, ps_sum = 0.0;
  const auto targets = bothDirections(r, e.title);
  for (const auto& t : targets) {
    const double x = (t.up + t.down) / 2.0, u = std::abs(t.up - t.down), ps = 6.0 * (t.s_up + t.s_down) / 2.0;
    mean.add(x, x);
    uncertainty.add(x + (u + ps) / 2.0, x - (u + ps) / 2.0);
    u_max = std::max(u_max, u), u_sum += u;
    ps_max = std::max(ps_max, ps), ps_sum += ps;
  }
  const auto n = static_cast<double>(targets.size());
  e.figures = {{"P", "Positionsunsicherheit (positional uncertainty)", uncertainty.span()},
               {"Pa", "Positionsabweichung (position deviation)", mean.span()},
               {"Ps max", "groesste Positionsstreubreite (largest positional scatter)", ps_max},
               {"Ps mean", "mittlere Positionsstreubreite (mean positional scatter)", ps_sum / n},
               {"U max", "groesste Umkehrspanne (largest reversal span)", u_max},
               {"U mean", "mittlere Umkehrspanne (mean reversal span)", u_sum / n}};
}

/// ASME B5.54 (as described in secondary sources): ISO 230-2's quantities with a +-3 s band.
void asmeB5_54(const Iso230Result& r, StandardEvaluation& e) {
  Range accuracy;
  double repeatability = 0.0, lost_max = 0.0, lost_sum = 0.0;
  const auto targets = bothDirections(r, e.title);
  for (const auto& t : targets) {
    accuracy.add(std::max(t.up + 3.0 * t.s_up, t.down + 3.0 * t.s_down),
                 std::min(t.up - 3.0 * t.s_up, t.down - 3.0 * t.s_down));
    const double b = std::abs(t.up - t.down);
    repeatability = std::max({repeatability, 3.0 * t.s_up + 3.0 * t.s_down + b, 6.0 * t.s_up, 6.0 * t.s_down});
    lost_max = std::max(lost_max, b), lost_sum += b;
  }
  e.figures = {{"accuracy", "bidirectional linear displacement accuracy (+-3 s)", accuracy.span()},
               {"repeatability", "bidirectional repeatability (+-3 s)", repeatability},
               {"lost motion", "largest reversal (lost motion)", lost_max},
               {"lost motion mean", "mean reversal (lost motion)", lost_sum / static_cast<double>(targets.size())}};
}

struct Standard {
  const char* name;
  const char* title;
  bool verified;
  const char* note;
  void (*evaluate)(const Iso230Result&, StandardEvaluation&);
};

const std::vector<Standard>& standards() {
  static const std::vector<Standard> all{
      {"iso230-2:2014", "ISO 230-2:2014", true, "", iso230_2},
      {"iso230-2:1997", "ISO 230-2:1997", false,
       "computed with the definitions of ISO 230-2:2006/2014 (+-2 s); that the 1997 edition defines them the same "
       "way is not verified against its text",
       iso230_2},
      {"jis-b6190-2", "JIS B 6190-2", true, "JIS B 6190-2 adopts ISO 230-2:2014: its figures and definitions",
       iso230_2},
      {"gb-t17421.2", "GB/T 17421.2", false,
       "GB/T 17421.2-2016 adopts ISO 230-2 (its scope names the annexes of the 2006 edition; the edition is not "
       "verified against its foreword): the figures of ISO 230-2:2006/2014",
       iso230_2},
      {"vdi3441", "VDI/DGQ 3441:1977", false,
       "the quantities' names are VDI/DGQ 3441's; their definitions come from secondary descriptions and are not "
       "verified against the guideline's text",
       vdi3441},
      {"asme-b5.54", "ASME B5.54", false,
       "the +-3 s definitions come from secondary descriptions and are not verified against the standard's text",
       asmeB5_54},
  };
  return all;
}

}  // namespace

double StandardEvaluation::value(std::string_view symbol) const {
  for (const auto& f : figures)
    if (f.symbol == symbol) return f.value_um;
  throw InputError(fmt::format("{} has no figure '{}'", title, symbol));
}

std::vector<std::string> positioningStandards() {
  std::vector<std::string> names;
  for (const auto& s : standards()) names.push_back(s.name);
  return names;
}

StandardEvaluation evaluateStandard(const Iso230Result& result, std::string_view standard) {
  for (const auto& s : standards()) {
    if (s.name != standard) continue;
    StandardEvaluation e{s.name, s.title, s.verified, s.note, {}};
    s.evaluate(result, e);
    return e;
  }
  throw InputError(
      fmt::format("unknown standard '{}' (one of: {})", standard, fmt::join(positioningStandards(), ", ")));
}

}  // namespace mtcal::processing
