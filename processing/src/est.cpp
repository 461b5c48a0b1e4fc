#include "mtcal/processing/est.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <random>

#include "mtcal/error.h"

namespace mtcal::processing {

bool sameStep(double step_mm, double first_step_mm) {
  return std::abs(step_mm - first_step_mm) <= 1e-6 * std::max(1.0, first_step_mm);
}

bool spacingFitsLine(double spacing_steps, std::size_t points) {
  return spacing_steps >= 1.0 && spacing_steps <= static_cast<double>(points) - 2.0;
}

namespace {

/// The even step of x and the probe spacing in steps. @throws InputError
int stepsPerSpacing(const std::vector<double>& x_mm, double spacing_mm, std::size_t min_points) {
  if (x_mm.size() < min_points) {
    throw InputError(fmt::format("EST: {} points, at least {} needed", x_mm.size(), min_points));
  }
  const double step = x_mm[1] - x_mm[0];
  if (!(step > 0.0)) throw InputError("EST: positions must increase");
  for (std::size_t k = 1; k < x_mm.size(); ++k) {
    if (!sameStep(x_mm[k] - x_mm[k - 1], step)) {
      throw InputError(
          fmt::format("EST: uneven steps (x = {} mm after {} mm; the step is {} mm)", x_mm[k], x_mm[k - 1], step));
    }
  }
  const double m = spacing_mm / step;
  if (!(spacing_mm > 0.0) || std::abs(m - std::round(m)) > 1e-6 || std::round(m) < 1) {
    throw InputError(
        fmt::format("EST: the probe spacing {} mm is not a whole number of steps of {} mm", spacing_mm, step));
  }
  if (!spacingFitsLine(std::round(m), x_mm.size())) {
    throw InputError(
        fmt::format("EST: the probe spacing {:g} mm is not shorter than the line read ({:g} to {:g} mm): "
                    "the second probe would never read where the first did",
                    spacing_mm, x_mm.front(), x_mm.back()));
  }
  return static_cast<int>(std::round(m));
}

void sameSize(const std::vector<double>& x, const std::vector<double>& v, const char* name) {
  if (v.size() != x.size())
    throw InputError(fmt::format("EST: {} has {} values for {} positions", name, v.size(), x.size()));
}

}  // namespace

EstResult separateTwoProbe(const std::vector<double>& x_mm, const std::vector<double>& v1_um,
                           const std::vector<double>& v2_um, double spacing_mm, EstStart start) {
  const int m = stepsPerSpacing(x_mm, spacing_mm, 2);
  sameSize(x_mm, v1_um, "v1");
  sameSize(x_mm, v2_um, "v2");
  if (start == EstStart::kSecondPointOnly && m != 1) {
    throw InputError("EST: the second-point start is defined for a spacing of one step");
  }
  const auto n = x_mm.size();
  const auto mm = static_cast<std::size_t>(m);
  // The profile is known at x_k for k < n + m - 1 (the front probe reaches further), but only
  // the carriage positions' samples are reported.
  std::vector<double> s(n + mm, 0.0);
  if (start == EstStart::kCarriageAtRest) {
    for (std::size_t j = 0; j < mm && j < n; ++j) s[j] = v1_um[j];
  } else {
    s[0] = 0.0;
    s[1] = v2_um[0];
  }
  const std::size_t first = start == EstStart::kCarriageAtRest ? 0 : 1;
  for (std::size_t k = first; k < n; ++k) s[k + mm] = s[k] + v2_um[k] - v1_um[k];
  EstResult r;
  r.x_mm = x_mm;
  r.profile_um.assign(s.begin(), s.begin() + static_cast<std::ptrdiff_t>(n));
  for (std::size_t k = 0; k < n; ++k) r.carriage_um.push_back(v1_um[k] - s[k]);
  return r;
}

EstResult separateThreeProbe(const std::vector<double>& x_mm, const std::vector<double>& v1_um,
                             const std::vector<double>& v2_um, const std::vector<double>& v3_um, double spacing_mm) {
  if (stepsPerSpacing(x_mm, spacing_mm, 3) != 1) {
    throw InputError("EST: the three-probe method here takes a probe spacing of one step");
  }
  sameSize(x_mm, v1_um, "v1");
  sameSize(x_mm, v2_um, "v2");
  sameSize(x_mm, v3_um, "v3");
  const auto n = x_mm.size();
  std::vector<double> s(n, 0.0);
  for (std::size_t k = 0; k + 2 < n; ++k) s[k + 2] = 2.0 * s[k + 1] - s[k] + (v3_um[k] - 2.0 * v2_um[k] + v1_um[k]);
  EstResult r;
  r.x_mm = x_mm;
  r.profile_um = s;
  return r;
}

EstResult separateFrequency(const std::vector<double>& x_mm, const std::vector<double>& v1_um,
                            const std::vector<double>& v2_um, double spacing_mm) {
  const int m = stepsPerSpacing(x_mm, spacing_mm, 4);
  sameSize(x_mm, v1_um, "v1");
  sameSize(x_mm, v2_um, "v2");
  const auto n = x_mm.size();
  const double step = x_mm[1] - x_mm[0];
  // d(k) = S(k + m) - S(k); a periodic model has no net rise: the mean of d is a slope of
  // mean(d) / m per step, removed here and put back as a line after the inversion.
  std::vector<double> d(n);
  double mean = 0.0;
  for (std::size_t k = 0; k < n; ++k) mean += (d[k] = v2_um[k] - v1_um[k]);
  mean /= static_cast<double>(n);
  std::vector<std::complex<double>> spectrum(n);
  const double two_pi = 2.0 * std::numbers::pi;
  for (std::size_t f = 0; f < n; ++f) {  // direct DFT: n is a few hundred at most
    std::complex<double> sum = 0.0;
    for (std::size_t k = 0; k < n; ++k) sum += (d[k] - mean) * std::polar(1.0, -two_pi * f * k / n);
    spectrum[f] = sum;
  }
  EstResult r;
  r.x_mm = x_mm;
  std::vector<std::complex<double>> profile(n, 0.0);
  for (std::size_t f = 1; f < n; ++f) {
    const std::complex<double> shift = std::polar(1.0, two_pi * f * m / n) - 1.0;
    if (std::abs(shift) < 1e-9) {
      if (f <= n / 2) r.lost_wavelengths_mm.push_back(static_cast<double>(n) * step / static_cast<double>(f));
      continue;
    }
    profile[f] = spectrum[f] / shift;
  }
  for (std::size_t k = 0; k < n; ++k) {
    std::complex<double> sum = 0.0;
    for (std::size_t f = 0; f < n; ++f) sum += profile[f] * std::polar(1.0, two_pi * f * k / n);
    r.profile_um.push_back(sum.real() / static_cast<double>(n) + mean / m * static_cast<double>(k));
  }
  const double first = r.profile_um.front();
  for (double& v : r.profile_um) v -= first;
  return r;
}

Straightness evaluateStraightness(const std::vector<double>& x_mm, const std::vector<double>& y_um) {
  const auto n = x_mm.size();
  if (n < 2 || y_um.size() != n) throw InputError("straightness: needs at least 2 points with a value each");
  for (std::size_t k = 1; k < n; ++k) {
    if (!(x_mm[k] > x_mm[k - 1])) throw InputError("straightness: positions must increase");
  }
  auto width = [&](double slope) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (std::size_t k = 0; k < n; ++k) {
      const double r = y_um[k] - slope * x_mm[k];
      lo = std::min(lo, r);
      hi = std::max(hi, r);
    }
    return hi - lo;
  };
  Straightness s;
  // Least squares.
  Eigen::MatrixXd a(static_cast<Eigen::Index>(n), 2);
  Eigen::VectorXd y(static_cast<Eigen::Index>(n));
  for (std::size_t k = 0; k < n; ++k) {
    a(static_cast<Eigen::Index>(k), 0) = 1.0;
    a(static_cast<Eigen::Index>(k), 1) = x_mm[k];
    y(static_cast<Eigen::Index>(k)) = y_um[k];
  }
  s.least_squares_um = width(a.colPivHouseholderQr().solve(y)(1));
  s.end_point_um = width((y_um.back() - y_um.front()) / (x_mm.back() - x_mm.front()));
  // Minimum zone: the width as a function of the slope is convex and piecewise linear, with
  // its minimum at the slope of an edge of the convex hull (the narrowest strip lies along a
  // hull edge). Monotone chain hull, then every edge slope.
  std::vector<std::size_t> hull;
  auto cross = [&](std::size_t o, std::size_t p, std::size_t q) {
    return (x_mm[p] - x_mm[o]) * (y_um[q] - y_um[o]) - (y_um[p] - y_um[o]) * (x_mm[q] - x_mm[o]);
  };
  for (int pass = 0; pass < 2; ++pass) {
    const std::size_t base = hull.size();
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t k = pass == 0 ? i : n - 1 - i;
      while (hull.size() >= base + 2 && cross(hull[hull.size() - 2], hull.back(), k) <= 0) hull.pop_back();
      hull.push_back(k);
    }
  }
  s.min_zone_um = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i + 1 < hull.size(); ++i) {
    const std::size_t p = hull[i], q = hull[i + 1];
    if (x_mm[p] == x_mm[q]) continue;
    const double slope = (y_um[q] - y_um[p]) / (x_mm[q] - x_mm[p]);
    const double w = width(slope);
    if (w < s.min_zone_um) {
      s.min_zone_um = w;
      s.min_zone_slope_um_per_mm = slope;
    }
  }
  return s;
}

std::vector<double> ignoredYawError(const std::vector<double>& gamma_rad, double spacing_mm) {
  std::vector<double> delta{0.0};
  double sum = 0.0;
  for (std::size_t i = 0; i + 1 < gamma_rad.size(); ++i) {
    sum += gamma_rad[i];
    delta.push_back(-spacing_mm * 1000.0 * sum);
  }
  return delta;
}

namespace {
/// Slope of the profile at each point (um/mm), central differences inside, one-sided at the ends.
std::vector<double> slopes(const std::vector<double>& x, const std::vector<double>& y) {
  const auto n = x.size();
  if (n < 2 || y.size() != n) throw InputError("EST error analysis: needs at least 2 points with a value each");
  std::vector<double> d(n);
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t a = k == 0 ? 0 : k - 1, b = k + 1 == n ? n - 1 : k + 1;
    d[k] = (y[b] - y[a]) / (x[b] - x[a]);
  }
  return d;
}
}  // namespace

std::vector<double> spacingErrorUm(const std::vector<double>& x_mm, const std::vector<double>& profile_um,
                                   double delta_l_mm) {
  const auto d = slopes(x_mm, profile_um);
  std::vector<double> out{0.0};
  double sum = 0.0;
  for (std::size_t i = 0; i + 1 < x_mm.size(); ++i) {
    sum += d[i + 1] * delta_l_mm;  // S' at x_i + l = x_{i+1}
    out.push_back(sum);
  }
  return out;
}

std::vector<double> stepErrorUm(const std::vector<double>& x_mm, const std::vector<double>& profile_um,
                                double delta_p_mm) {
  const auto d = slopes(x_mm, profile_um);
  std::vector<double> out{0.0};
  double sum = 0.0;
  for (std::size_t i = 0; i + 1 < x_mm.size(); ++i) {
    sum += (d[i + 1] - d[i]) * static_cast<double>(i) * delta_p_mm;
    out.push_back(sum);
  }
  return out;
}

double twoProbeNoiseUm(int k, double sigma_um) { return sigma_um * std::sqrt(2.0 * k + 1.0); }

double threeProbeNoiseUm(int k, double sigma_um) {
  double sum = 0.0;
  for (int j = 1; j < k; ++j) sum += static_cast<double>(j) * j;
  return sigma_um * std::sqrt(6.0 * sum);
}

Budget combineBudget(const std::vector<BudgetItem>& items, int samples, unsigned seed) {
  Budget b;
  double variance = 0.0;
  for (const auto& item : items) {
    b.linear_sum_um += std::abs(item.value_um);
    variance += item.bound ? item.value_um * item.value_um / 3.0 : item.value_um * item.value_um;
  }
  b.root_sum_square_um = std::sqrt(variance);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  std::vector<double> sums(static_cast<std::size_t>(samples));
  double sum = 0.0, ss = 0.0;
  for (auto& total : sums) {
    total = 0.0;
    for (const auto& item : items) total += item.value_um * (item.bound ? uniform(rng) : normal(rng));
    sum += total;
    ss += total * total;
  }
  const double n = static_cast<double>(samples);
  b.monte_carlo_sigma_um = std::sqrt(ss / n - (sum / n) * (sum / n));
  for (auto& v : sums) v = std::abs(v);
  const auto q = sums.begin() + static_cast<std::ptrdiff_t>(0.95 * n);
  std::nth_element(sums.begin(), q, sums.end());
  b.monte_carlo_95_um = *q;
  return b;
}

}  // namespace mtcal::processing
