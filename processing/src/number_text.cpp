#include "mtcal/processing/number_text.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace mtcal::processing {

namespace {

/// The power of ten of `size`'s leading digit once rounded to `digits` digits (9.9996 to four is 10.00: 1).
int leadingExponent(double size, int digits) {
  int exponent = static_cast<int>(std::floor(std::log10(size)));
  if (std::round(size / std::pow(10.0, exponent - digits + 1)) >= std::pow(10.0, digits)) ++exponent;
  return exponent;
}

}  // namespace

std::string significant(double value, int digits) {
  const double size = std::abs(value);
  if (!(size >= 1e-6 && size < 1e6)) return fmt::format("{:.{}g}", value, digits);  // NaN and infinity too
  const int exponent = leadingExponent(size, digits);
  if (exponent >= 6) return fmt::format("{:.{}g}", value, digits);
  const double unit = std::pow(10.0, exponent - digits + 1);
  return fmt::format("{:.{}f}", std::round(value / unit) * unit, std::max(0, digits - 1 - exponent));
}

double roundedTo(double value, int decimals) {
  const double unit = std::pow(10.0, decimals);
  const double rounded = std::round(value * unit) / unit;
  return rounded == 0.0 ? 0.0 : rounded;
}

std::string valueWithUncertainty(double value, double standard_error, const std::string& separator) {
  if (!(standard_error > 0.0) || !std::isfinite(standard_error) || !std::isfinite(value))
    return significant(value, 4) + (std::isfinite(standard_error) && standard_error > 0.0
                                        ? separator + significant(standard_error, 2)
                                        : std::string());
  const std::string error_text = significant(standard_error, 2);
  const double size = std::abs(value);
  // The value to the standard error's last digit (GUM 7.2.6: the estimate rounded to the same
  // digit as its uncertainty), in fixed form.
  if (standard_error >= 1e-6 && standard_error < 1e6 && size < 1e6) {
    const int last = leadingExponent(standard_error, 2) - 1;
    const double unit = std::pow(10.0, last);
    const double rounded = std::round(value / unit) * unit;
    return fmt::format("{:.{}f}", rounded == 0.0 ? 0.0 : rounded, std::max(0, -last)) + separator + error_text;
  }
  // Beyond, both in the power of ten of the larger, where the standard error is then 1e-4 or
  // more: (1.20 +- 0.46)e7, not 1.2e+07 +- 4.6e+05; else each to its own digits.
  const int exponent = leadingExponent(std::max(size, standard_error), 2);
  const double scale = std::pow(10.0, exponent);
  if (standard_error / scale >= 1e-4) {
    return "(" + valueWithUncertainty(value / scale, standard_error / scale, separator) + ")e" +
           std::to_string(exponent);
  }
  return significant(value, 4) + separator + error_text;
}

std::string sizeText(double value) {
  return std::abs(value) >= 0.1 || value == 0.0 ? fmt::format("{:.3f}", value) : significant(value, 3);
}

}  // namespace mtcal::processing
