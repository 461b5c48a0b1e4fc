#include "mtcal/acquisition/capture.h"

#include <cmath>

namespace mtcal::acquisition {

WindowStats windowStats(std::span<const drivers::Sample> window, double to_um) {
  WindowStats st;
  const std::size_t n = window.size();
  if (n < 2) return st;
  // Welford-free two-pass: windows are small and exact means matter more than speed here.
  double sum = 0.0, first = 0.0, second = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    sum += window[i].value;
    (i < n / 2 ? first : second) += window[i].value;
    if (!window[i].beam_ok) ++st.beam_lost;
  }
  st.mean = sum / n;
  double ss = 0.0;
  for (const auto& s : window) ss += (s.value - st.mean) * (s.value - st.mean);
  st.stddev_um = std::sqrt(ss / (n - 1)) * to_um;
  st.drift_um = std::abs(second / (n - n / 2) - first / (n / 2)) * to_um;
  return st;
}

}  // namespace mtcal::acquisition
