#include "mtcal/processing/iso230_2.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <string>

#include "mtcal/error.h"

namespace mtcal::processing {
namespace {

struct Stats {
  int n = 0;
  double mean = 0.0;
  double s = 0.0;
};

Stats meanAndS(const std::vector<double>& values) {
  Stats st;
  st.n = static_cast<int>(values.size());
  for (double v : values) st.mean += v;
  st.mean /= st.n;
  double ss = 0.0;
  for (double v : values) ss += (v - st.mean) * (v - st.mean);
  st.s = std::sqrt(ss / (st.n - 1));
  return st;
}

// Accumulates the largest "high" and the smallest "low" candidate over all positions.
struct Range {
  double max_v = -std::numeric_limits<double>::infinity();
  double min_v = std::numeric_limits<double>::infinity();
  void high(std::optional<double> v) {
    if (v) max_v = std::max(max_v, *v);
  }
  void low(std::optional<double> v) {
    if (v) min_v = std::min(min_v, *v);
  }
  void both(std::optional<double> v) {
    high(v);
    low(v);
  }
  std::optional<double> width() const {
    if (!std::isfinite(max_v) || !std::isfinite(min_v)) return std::nullopt;
    return max_v - min_v;
  }
};

void takeMax(std::optional<double>& best, std::optional<double> v) {
  if (v) best = best ? std::max(*best, *v) : *v;
}

std::optional<double> plus(std::optional<double> a, std::optional<double> b, double k) {
  if (!a || !b) return std::nullopt;
  return *a + k * *b;
}

}  // namespace

Iso230Result evaluateIso230_2(std::span<const PositionDeviation> deviations) {
  // Group by target rounded to 1 nm, then by direction.
  struct Group {
    double target_mm = 0.0;
    std::vector<double> up, down;
    std::set<int> cycles_up, cycles_down;
  };
  std::map<long long, Group> groups;
  for (const auto& d : deviations) {
    if (!std::isfinite(d.target_mm) || !std::isfinite(d.deviation_um)) {
      throw InputError("ISO 230-2: non-finite target or deviation at target " + std::to_string(d.target_mm));
    }
    auto& g = groups[std::llround(d.target_mm * 1e6)];
    g.target_mm = d.target_mm;
    auto& cycles = d.direction == Direction::kUp ? g.cycles_up : g.cycles_down;
    if (!cycles.insert(d.cycle).second) {
      throw InputError("ISO 230-2: cycle " + std::to_string(d.cycle) + " appears twice at target " +
                       std::to_string(d.target_mm) + " mm, direction " +
                       (d.direction == Direction::kUp ? "up" : "down"));
    }
    (d.direction == Direction::kUp ? g.up : g.down).push_back(d.deviation_um);
  }
  if (groups.size() < 2) throw InputError("ISO 230-2: at least 2 target positions are needed");

  const bool any_up = std::any_of(groups.begin(), groups.end(), [](auto& kv) { return !kv.second.up.empty(); });
  const bool any_down = std::any_of(groups.begin(), groups.end(), [](auto& kv) { return !kv.second.down.empty(); });

  Iso230Result result;
  result.min_cycles = std::numeric_limits<int>::max();
  for (auto& [key, g] : groups) {
    Iso230Position p;
    p.target_mm = g.target_mm;
    for (auto [present, values, label] : {std::tuple{any_up, &g.up, "up"}, std::tuple{any_down, &g.down, "down"}}) {
      if (!present) continue;
      if (values->size() < 2) {
        throw InputError("ISO 230-2: target " + std::to_string(g.target_mm) + " mm has " +
                         std::to_string(values->size()) + " cycle(s) in direction " + label +
                         "; at least 2 are needed to estimate s");
      }
      result.min_cycles = std::min(result.min_cycles, static_cast<int>(values->size()));
    }
    if (any_up) {
      Stats st = meanAndS(g.up);
      p.cycles_up = st.n;
      p.mean_up_um = st.mean;
      p.s_up_um = st.s;
      p.repeatability_up_um = 4.0 * st.s;
    }
    if (any_down) {
      Stats st = meanAndS(g.down);
      p.cycles_down = st.n;
      p.mean_down_um = st.mean;
      p.s_down_um = st.s;
      p.repeatability_down_um = 4.0 * st.s;
    }
    if (any_up && any_down) {
      p.mean_um = (*p.mean_up_um + *p.mean_down_um) / 2.0;
      p.reversal_um = *p.mean_up_um - *p.mean_down_um;
      p.repeatability_um = std::max({2.0 * *p.s_up_um + 2.0 * *p.s_down_um + std::abs(*p.reversal_um),
                                     *p.repeatability_up_um, *p.repeatability_down_um});
    }
    result.positions.push_back(p);
  }

  Range e_up, e_down, e_bi, m_bi, a_up, a_down, a_bi;
  double sum_b = 0.0;
  for (const auto& p : result.positions) {
    takeMax(result.R_up_um, p.repeatability_up_um);
    takeMax(result.R_down_um, p.repeatability_down_um);
    takeMax(result.R_um, p.repeatability_um);
    e_up.both(p.mean_up_um);
    e_down.both(p.mean_down_um);
    e_bi.both(p.mean_up_um);
    e_bi.both(p.mean_down_um);
    m_bi.both(p.mean_um);
    a_up.high(plus(p.mean_up_um, p.s_up_um, 2.0));
    a_up.low(plus(p.mean_up_um, p.s_up_um, -2.0));
    a_down.high(plus(p.mean_down_um, p.s_down_um, 2.0));
    a_down.low(plus(p.mean_down_um, p.s_down_um, -2.0));
    if (p.reversal_um) {
      takeMax(result.B_um, std::abs(*p.reversal_um));
      sum_b += *p.reversal_um;
    }
  }
  result.E_up_um = e_up.width();
  result.E_down_um = e_down.width();
  result.A_up_um = a_up.width();
  result.A_down_um = a_down.width();
  if (any_up && any_down) {
    result.B_mean_um = sum_b / static_cast<double>(result.positions.size());
    result.E_um = e_bi.width();
    result.M_um = m_bi.width();
    Range a = a_up;
    a.high(a_down.max_v);
    a.low(a_down.min_v);
    result.A_um = a.width();
  }
  return result;
}

}  // namespace mtcal::processing
