#pragma once
// Counter-based random numbers: a value depends only on (seed, stream, index), never on
// how many values were drawn before or on thread timing. This is what keeps a simulated
// campaign identical for the same seed although the instrument streams in real time.

#include <cmath>
#include <cstdint>
#include <numbers>

namespace mtcal::mocks {

/// SplitMix64 finaliser (Steele, Lea & Flood 2014): a bijective 64-bit mix.
constexpr std::uint64_t mix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

/// Uniform in (0, 1) from a key.
inline double uniformFromKey(std::uint64_t key) {
  return (static_cast<double>(mix64(key) >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}

/// Standard normal N(0,1) for (seed, stream, index), by Box-Muller on two keyed uniforms.
inline double normalFromKey(std::uint64_t seed, std::uint64_t stream, std::uint64_t index) {
  const std::uint64_t base = mix64(seed ^ mix64(stream * 0x632BE59BD9B4E019ULL + index));
  const double u1 = uniformFromKey(base);
  const double u2 = uniformFromKey(base ^ 0xD6E8FEB86659FD93ULL);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
}

}  // namespace mtcal::mocks
