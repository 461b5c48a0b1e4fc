#include "mtcal/processing/compensation.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "mtcal/error.h"

namespace mtcal::processing {
namespace {

/// Index k with position[k] <= x < position[k + 1] (position.size() >= 2, x inside).
std::size_t segmentOf(const std::vector<double>& position, double x) {
  const auto it = std::upper_bound(position.begin(), position.end(), x);
  const auto k = static_cast<std::size_t>(std::max<std::ptrdiff_t>(it - position.begin() - 1, 0));
  return std::min(k, position.size() - 2);
}

double lerp(double x0, double x1, double y0, double y1, double x) {
  return x1 == x0 ? y0 : y0 + (y1 - y0) * (x - x0) / (x1 - x0);
}

const std::vector<double>& valuesOf(const CompensationTable& t, Direction d) {
  return d == Direction::kUp ? t.up_um : t.down_um;
}

}  // namespace

double AxisError::at(double x, Direction direction) const {
  if (position.size() < 2) throw InputError("axis error: fewer than 2 positions");
  const double tolerance = 1e-9 * std::max(1.0, std::abs(position.back() - position.front()));
  if (!(x >= position.front() - tolerance && x <= position.back() + tolerance)) {
    throw InputError(
        fmt::format("position {:g} is outside the measured range [{:g}, {:g}]", x, position.front(), position.back()));
  }
  const auto& v = direction == Direction::kUp ? up_um : down_um;
  const std::size_t k = segmentOf(position, x);
  return lerp(position[k], position[k + 1], v[k], v[k + 1], x);
}

AxisError axisErrorOf(const Iso230Result& evaluation) {
  AxisError e;
  for (const auto& p : evaluation.positions) {
    if (!p.mean_up_um && !p.mean_down_um)
      throw InputError(fmt::format("target {:g}: no mean deviation in either direction", p.target_mm));
    e.position.push_back(p.target_mm);
    e.up_um.push_back(p.mean_up_um.value_or(p.mean_down_um.value_or(0.0)));
    e.down_um.push_back(p.mean_down_um.value_or(p.mean_up_um.value_or(0.0)));
  }
  return e;
}

double CompensationTable::correctionUm(double x, Direction direction, const TableRules& rules) const {
  const auto& v = valuesOf(*this, direction);
  const double first = position.front(), last = position.back();
  if (modulo) {
    x = first + std::fmod(std::fmod(x - first, *modulo) + *modulo, *modulo);
    if (x >= last) {
      // From the last entry round to the first one, a period on.
      return rules.interpolate ? lerp(last, first + *modulo, v.back(), v.front(), x) : v.back();
    }
  } else if (x < first || x > last) {
    if (!rules.hold_beyond) return 0.0;
    return x < first ? v.front() : v.back();
  }
  const std::size_t k = segmentOf(position, x);
  if (!rules.interpolate) return x >= position[k + 1] ? v[k + 1] : v[k];
  return lerp(position[k], position[k + 1], v[k], v[k + 1], x);
}

void checkTable(const CompensationTable& t, const char* source) {
  if (t.position.size() < 2) throw InputError(fmt::format("{}: a table needs at least 2 entries", source));
  if (t.up_um.size() != t.position.size() || t.down_um.size() != t.position.size())
    throw InputError(fmt::format("{}: {} positions but {} and {} values", source, t.position.size(), t.up_um.size(),
                                 t.down_um.size()));
  for (std::size_t i = 0; i < t.position.size(); ++i) {
    if (!std::isfinite(t.position[i]) || !std::isfinite(t.up_um[i]) || !std::isfinite(t.down_um[i]))
      throw InputError(fmt::format("{}: entry {}: a value is not a finite number", source, i + 1));
    if (i > 0 && !(t.position[i] > t.position[i - 1]))
      throw InputError(fmt::format("{}: entry {}: position {:g} does not increase (the one before is {:g})", source,
                                   i + 1, t.position[i], t.position[i - 1]));
  }
  if (t.modulo && !(*t.modulo > 0.0 && t.position.back() - t.position.front() < *t.modulo))
    throw InputError(fmt::format("{}: the entries span {:g}, not less than the modulo {:g}", source,
                                 t.position.back() - t.position.front(), *t.modulo));
}

void checkInterval(double interval_mm, const std::string& what) {
  if (!(interval_mm > 0.0) || !std::isfinite(interval_mm))
    throw InputError(fmt::format("{}: interval {:g} is not a positive number", what, interval_mm));
  if (interval_mm < kFinestIntervalMm)
    throw InputError(fmt::format("{}: the interval {:g} mm is finer than {:g} mm (mm, not um?)", what, interval_mm,
                                 kFinestIntervalMm));
}

void checkTableOptions(const TableOptions& o) {
  for (const auto& [name, given] :
       {std::pair{"start", o.start}, std::pair{"end", o.end}, std::pair{"reference point", o.reference}}) {
    if (given && !std::isfinite(*given))
      throw InputError(fmt::format("compensation: the {} {:g} is not a number", name, *given));
  }
  if (o.interval) checkInterval(*o.interval, "compensation");
  if (o.modulo && !(*o.modulo > 0.0 && std::isfinite(*o.modulo)))
    throw InputError(fmt::format("compensation: modulo {:g} is not positive", *o.modulo));
  if (!(o.resolution_um >= 0.0 && o.resolution_um <= kCoarsestResolutionUm))
    throw InputError(
        fmt::format("compensation: a resolution of {:g} um is not 0..{:g} um (a controller's is 0.1..1 um)",
                    o.resolution_um, kCoarsestResolutionUm));
}

CompensationTable compensationTable(const AxisError& measured, const TableOptions& o, const CompensationTable* existing,
                                    const TableRules& existing_rules) {
  checkTableOptions(o);
  if (measured.position.size() < 2) throw InputError("compensation: the measured error has fewer than 2 positions");
  const double start = o.start.value_or(measured.position.front());
  double end = o.end.value_or(measured.position.back());
  CompensationTable t;
  t.modulo = o.modulo;
  if (!o.interval) {
    // Entries at the measured positions: a start or end given must be one of them.
    for (const auto& [name, given] : {std::pair{"start", o.start}, std::pair{"end", o.end}}) {
      if (!given) continue;
      const bool measured_there = std::any_of(measured.position.begin(), measured.position.end(),
                                              [&](double x) { return std::abs(x - *given) < 1e-9; });
      if (!measured_there) {
        throw InputError(fmt::format(
            "compensation: {} {:g} is not a measured position (the measured range is {:g} to {:g}): give one of "
            "them, or --interval for entries on a grid",
            name, *given, measured.position.front(), measured.position.back()));
      }
    }
    for (double x : measured.position)
      if (x >= start - 1e-9 && x <= end + 1e-9) t.position.push_back(x);
  } else {
    const double step = *o.interval;
    if (!(end > start)) throw InputError(fmt::format("compensation: end {:g} is not after start {:g}", end, start));
    const double steps = (end - start) / step;
    const double whole = std::round(steps);
    if (std::abs(steps - whole) > 1e-6)
      throw InputError(
          fmt::format("compensation: the interval {:g} does not divide the range {:g} to {:g} ({:g} "
                      "intervals); choose an interval or an end that fits",
                      step, start, end, steps));
    // With a modulo the last position, a period on from the first, is the first one again.
    const auto n = static_cast<std::size_t>(whole) + (o.modulo && std::abs(end - start - *o.modulo) < 1e-9 ? 0 : 1);
    for (std::size_t i = 0; i < n; ++i) t.position.push_back(start + static_cast<double>(i) * step);
  }
  if (t.position.size() < 2)
    throw InputError(fmt::format("compensation: fewer than 2 positions from {:g} to {:g}", start, end));
  if (o.max_points > 0 && t.position.size() > o.max_points) {
    throw InputError(fmt::format("compensation: {} entries, the controller takes at most {}: choose a larger interval",
                                 t.position.size(), o.max_points));
  }
  for (double x : t.position) {
    double up = -measured.at(x, Direction::kUp), down = -measured.at(x, Direction::kDown);
    if (existing) {
      up += existing->correctionUm(x, Direction::kUp, existing_rules);
      down += existing->correctionUm(x, Direction::kDown, existing_rules);
    }
    if (!o.bidirectional) up = down = (up + down) / 2.0;
    t.up_um.push_back(up);
    t.down_um.push_back(down);
  }
  if (o.reference) {
    const auto at = [&](Direction d) {
      // The table before rounding, read as the controller would (linear between entries).
      CompensationTable raw = t;
      raw.modulo.reset();
      return raw.correctionUm(*o.reference, d);
    };
    if (*o.reference < t.position.front() - 1e-9 || *o.reference > t.position.back() + 1e-9) {
      throw InputError(fmt::format("compensation: the reference point {:g} is outside the table [{:g}, {:g}]",
                                   *o.reference, t.position.front(), t.position.back()));
    }
    const double zero = (at(Direction::kUp) + at(Direction::kDown)) / 2.0;
    for (auto& v : t.up_um) v -= zero;
    for (auto& v : t.down_um) v -= zero;
  }
  if (o.resolution_um > 0.0) {
    const auto round = [&](double v) { return std::round(v / o.resolution_um) * o.resolution_um; };
    for (auto& v : t.up_um) v = round(v);
    for (auto& v : t.down_um) v = round(v);
  }
  checkTable(t, "compensation");
  return t;
}

}  // namespace mtcal::processing
