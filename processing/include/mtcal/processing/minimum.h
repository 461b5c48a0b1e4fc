#pragma once
// The minimum of a function of one variable on an interval, without derivatives.

#include <algorithm>
#include <cmath>
#include <utility>

namespace mtcal::processing {

/// The minimum of f on [low, high] to `tolerance` in its argument, and f there: Brent's method
/// (R. P. Brent, Algorithms for Minimization without Derivatives, 1973, ch. 5), a parabola
/// through the three best points where it steps inside the interval and shrinks it fast enough,
/// else a golden section step; a smooth minimum takes a few steps where golden sections alone
/// take twenty. f has one minimum on the interval: where it rises from `low`, the minimum is
/// within the tolerance of `low` (two evaluations).
template <class Function>
std::pair<double, double> brentMinimum(const Function& f, double low, double high, double tolerance) {
  if (const double f_low = f(low); f_low <= f(std::min(high, low + 2.0 * tolerance))) return {low, f_low};
  const double golden = 0.5 * (3.0 - std::sqrt(5.0));
  double best = low + golden * (high - low), second = best, third = best;  // x, w, v
  double f_best = f(best), f_second = f_best, f_third = f_best;
  double step = 0.0, previous_step = 0.0;
  for (int k = 0; k < 100; ++k) {
    const double middle = 0.5 * (low + high);
    if (std::abs(best - middle) <= 2.0 * tolerance - 0.5 * (high - low)) break;
    bool parabolic = false;
    if (std::abs(previous_step) > tolerance) {
      const double r = (best - second) * (f_best - f_third);
      double q = (best - third) * (f_best - f_second);
      double p = (best - third) * q - (best - second) * r;
      q = 2.0 * (q - r);
      if (q > 0.0) p = -p;
      q = std::abs(q);
      const double before = previous_step;
      previous_step = step;
      // The parabola's step: inside the interval and less than half the step before last.
      if (std::abs(p) < std::abs(0.5 * q * before) && p > q * (low - best) && p < q * (high - best)) {
        step = p / q;
        const double next = best + step;
        if (next - low < 2.0 * tolerance || high - next < 2.0 * tolerance)
          step = middle >= best ? tolerance : -tolerance;
        parabolic = true;
      }
    }
    if (!parabolic) {
      previous_step = best >= middle ? low - best : high - best;
      step = golden * previous_step;
    }
    const double next = best + (std::abs(step) >= tolerance ? step : std::copysign(tolerance, step));
    const double f_next = f(next);
    if (f_next <= f_best) {
      (next >= best ? low : high) = best;
      third = second, f_third = f_second;
      second = best, f_second = f_best;
      best = next, f_best = f_next;
    } else {
      (next < best ? low : high) = next;
      if (f_next <= f_second || second == best) {
        third = second, f_third = f_second;
        second = next, f_second = f_next;
      } else if (f_next <= f_third || third == best || third == second) {
        third = next, f_third = f_next;
      }
    }
  }
  return {best, f_best};
}

}  // namespace mtcal::processing
