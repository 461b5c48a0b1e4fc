// FANUC pitch error compensation (Series 0i/16i/30i, parameters 3620-3627 and the pitch error
// data): values incremental per interval, in detection units times a magnification, counted
// from the reference position; a parameter tape file (ISO code, one record a line). Sources and
// what is not verified: docs/compensation.md.

#include <fmt/format.h>

#include <cmath>
#include <map>
#include <regex>

#include "compensation_text.h"
#include "mtcal/error.h"

namespace mtcal::processing::format_text {
namespace {

constexpr double kDetectionUnitUm = 1.0;  ///< IS-B on a metric machine: 0.001 mm
constexpr int kMaxIncrement = 7;          ///< a point's value, in magnified detection units
constexpr int kMaxMagnification = 100;
constexpr int kNumbersPerAxis = 128;    ///< the compensation numbers mtcal gives each axis
constexpr int kDataRecordBase = 10000;  ///< pitch error data N10000 + compensation number
constexpr long kMaxNumber = 1023;       ///< the compensation numbers mtcal reads: 0 to 1023

/// A table in Fanuc's terms: points from `first_number`, the reference one, values per point.
struct PitchTable {
  int reference = 0, most_negative = 0, most_positive = 0, magnification = 1;
  long interval_du = 0;
  std::optional<long> travel_per_rotation_du;
  std::vector<long> up, down;  ///< absolute, in magnified detection units, zero at the reference moving up
  std::optional<int> negative_first;
  long negative_at_reference_du = 0;
};

/// Incremental values per point from absolute ones: the value at a point is the change over the
/// interval on its negative side; the first point's (nothing below it) is 0, or on a rotary
/// axis the last point's (the same interval, a period on).
std::vector<long> increments(const std::vector<long>& absolute, bool rotary) {
  std::vector<long> d(absolute.size(), 0);
  for (std::size_t e = 1; e < absolute.size(); ++e) d[e] = absolute[e] - absolute[e - 1];
  if (rotary) d[0] = d.back();
  return d;
}

ControllerFile writeFanuc(const CompensationTable& table, const AxisOfTable& axis) {
  if (axis.index < 0 || (axis.index + 1) * kNumbersPerAxis - 1 > kMaxNumber) {
    throw InputError(
        fmt::format("Fanuc: axis number {}: mtcal gives axis n the compensation numbers {} n to {} n + {} "
                    "of 0 to {}, so its axes are 0 to {} (--axis-index)",
                    axis.index, kNumbersPerAxis, kNumbersPerAxis, kNumbersPerAxis - 1, kMaxNumber,
                    (kMaxNumber + 1) / kNumbersPerAxis - 1));
  }
  const double step = equidistantStep(table, "Fanuc");
  const auto t = withPeriodEnd(table);
  std::size_t r = t.position.size();
  for (std::size_t e = 0; e < t.position.size(); ++e)
    if (std::abs(t.position[e]) < 1e-9) r = e;
  if (r == t.position.size() || (t.modulo && r != 0)) {
    throw InputError(fmt::format(
        "Fanuc counts the compensation points from the reference position (0 {}): the table needs an entry at "
        "0{}; measure from 0 (a plan whose targets start there) and put 0 on the table's grid (--start, "
        "--interval)",
        t.modulo ? "deg" : "mm", t.modulo ? ", its first" : ""));
  }
  const double interval_du = step * kUmPerMm / kDetectionUnitUm;
  if (std::abs(interval_du - std::round(interval_du)) > 1e-6)
    throw InputError(fmt::format("Fanuc: the interval {:g} is not a whole number of detection units (0.001)", step));
  // Fanuc's correction is zero at the reference position approached moving positive.
  const double shift_um = t.up_um[r];
  const bool bidirectional = t.bidirectional();
  PitchTable p;
  std::vector<long> up_d, down_d;
  for (p.magnification = 1; p.magnification <= kMaxMagnification; ++p.magnification) {
    const double unit_um = kDetectionUnitUm * p.magnification;
    p.up.clear(), p.down.clear();
    for (std::size_t e = 0; e < t.position.size(); ++e) {
      p.up.push_back(std::lround((t.up_um[e] - shift_um) / unit_um));
      p.down.push_back(std::lround((t.down_um[e] - shift_um) / unit_um));
    }
    up_d = increments(p.up, t.modulo.has_value());
    down_d = increments(p.down, t.modulo.has_value());
    const auto fits = [](const std::vector<long>& d) {
      return std::all_of(d.begin(), d.end(), [](long v) { return std::abs(v) <= kMaxIncrement; });
    };
    if (fits(up_d) && fits(down_d)) break;
  }
  if (p.magnification > kMaxMagnification)
    throw InputError("Fanuc: the correction changes by more than 700 um over one interval: choose a smaller interval");
  const int count = static_cast<int>(t.position.size());
  const int base = axis.index * kNumbersPerAxis;
  if (count * (bidirectional ? 2 : 1) > kNumbersPerAxis) {
    throw InputError(fmt::format(
        "Fanuc: {} points{} do not fit in the {} compensation numbers of axis {} ({} to {}): "
        "choose a larger interval",
        count, bidirectional ? " per direction" : "", kNumbersPerAxis, axis.name, base, base + kNumbersPerAxis - 1));
  }
  const int a = axis.index + 1;
  ControllerFile f;
  f.extension = ".prm";
  f.text = "%\n";
  f.text += fmt::format("N03620A{}P{}\nN03621A{}P{}\nN03622A{}P{}\nN03623A{}P{}\nN03624A{}P{}\n", a, base + r, a, base,
                        a, base + count - 1, a, p.magnification, a, std::lround(interval_du));
  if (t.modulo) f.text += fmt::format("N03625A{}P{}\n", a, std::lround(*t.modulo * kUmPerMm / kDetectionUnitUm));
  const int negative_base = base + count;
  const long negative_at_reference = std::lround(p.down[r] * p.magnification * kDetectionUnitUm);
  if (bidirectional) f.text += fmt::format("N03626A{}P{}\nN03627A{}P{}\n", a, negative_base, a, negative_at_reference);
  for (int e = 0; e < count; ++e) f.text += fmt::format("N{}P{}\n", kDataRecordBase + base + e, up_d[e]);
  if (bidirectional)
    for (int e = 0; e < count; ++e) f.text += fmt::format("N{}P{}\n", kDataRecordBase + negative_base + e, down_d[e]);
  f.text += "%\n";
  f.setup = fmt::format(
      "axis {0} (A{1}): compensation points {2} to {3}, reference point {4} at 0, interval {5:g} "
      "{6}, magnification {7} (a value of 1 is {7} um)\n"
      "the table is shifted by {8:+.3f} um: Fanuc's correction is zero at the reference position approached moving "
      "positive\n{9}"
      "power off and on after loading, then return to the reference position\n",
      axis.name, a, base, base + count - 1, base + r, step, t.modulo ? "deg" : "mm", p.magnification, -shift_um + 0.0,
      bidirectional ? fmt::format("bidirectional: set parameter 3605#0 (BDP) of axis A{} to 1 (the file leaves the "
                                  "other bits of 3605 as they are); negative direction: points {} to {}, {} um at the "
                                  "reference (3627)\n",
                                  a, negative_base, negative_base + count - 1, negative_at_reference)
                    : "");
  return f;
}

CompensationTable readFanuc(std::string_view text, const std::string& source) {
  static const std::regex kRecord(R"(\s*N(\d{1,5})(?:A(\d{1,2}))?P(-?\d+)\s*;?\s*)");
  const auto lines = linesOf(text);
  std::map<int, long> parameter, data;
  std::optional<std::string> axis;
  std::size_t percent = 0;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const std::string& line = lines[i];
    if (line.find_first_not_of(" \t") == std::string::npos) continue;
    if (line.find_first_not_of(" \t%") == std::string::npos) {
      ++percent;
      continue;
    }
    std::smatch m;
    if (!std::regex_match(line, m, kRecord))
      throw InputError(
          fmt::format("{}: line {}: '{}' is not a record N<number>[A<axis>]P<value>", source, i + 1, line));
    const int number = std::stoi(m[1]);
    if (m[3].length() > 10) {
      throw InputError(
          fmt::format("{}: line {}: value {} is beyond what the controller holds", source, i + 1, m[3].str()));
    }
    const long value = std::stol(m[3]);
    if (number >= kDataRecordBase) {
      if (!data.emplace(number - kDataRecordBase, value).second)
        throw InputError(
            fmt::format("{}: line {}: compensation point {} given twice", source, i + 1, number - kDataRecordBase));
    } else {
      if (!m[2].matched)
        throw InputError(fmt::format("{}: line {}: parameter {} names no axis", source, i + 1, number));
      if (axis && *axis != m[2])
        throw InputError(fmt::format("{}: line {}: a second axis: mtcal reads one", source, i + 1));
      axis = m[2];
      parameter[number] = value;
    }
  }
  if (percent < 2) throw InputError(fmt::format("{}: a parameter file begins and ends with a % line", source));
  const auto need = [&](int number) {
    const auto it = parameter.find(number);
    if (it == parameter.end()) throw InputError(fmt::format("{}: parameter {} is missing", source, number));
    return it->second;
  };
  const long reference = need(3620), first = need(3621), last = need(3622), magnification = need(3623),
             interval_du = need(3624);
  for (const long number : {reference, first, last}) {
    if (number < 0 || number > kMaxNumber)
      throw InputError(fmt::format("{}: compensation point {} is not one of 0 to {}", source, number, kMaxNumber));
  }
  if (parameter.count(3626) && (need(3626) < 0 || need(3626) + (last - first) > kMaxNumber))
    throw InputError(
        fmt::format("{}: parameter 3626: the negative direction's points are not within 0 to {}", source, kMaxNumber));
  if (magnification > kMaxMagnification)
    throw InputError(fmt::format("{}: parameter 3623: magnification {} is beyond FANUC's {}", source, magnification,
                                 kMaxMagnification));
  if (!(first <= reference && reference <= last) || interval_du <= 0 || magnification <= 0) {
    throw InputError(
        fmt::format("{}: parameters 3620-3624: reference {} not within points {} to {}, or interval {} "
                    "or magnification {} not positive",
                    source, reference, first, last, interval_du, magnification));
  }
  const auto absolute = [&](long from) {
    // Points from..from + (last - first), summed from the reference point's.
    std::vector<double> um;
    const long r = from + (reference - first);
    const auto at = [&](long n) {
      const auto it = data.find(static_cast<int>(n));
      if (it == data.end()) throw InputError(fmt::format("{}: no value for compensation point {}", source, n));
      if (std::abs(it->second) > kMaxIncrement)
        throw InputError(
            fmt::format("{}: compensation point {}: {} is beyond FANUC's -{} to +{} (units of the "
                        "magnification, parameter 3623)",
                        source, n, it->second, kMaxIncrement, kMaxIncrement));
      return static_cast<double>(it->second * magnification) * kDetectionUnitUm;
    };
    for (long n = from; n <= from + (last - first); ++n) {
      double sum = 0.0;
      for (long k = r + 1; k <= n; ++k) sum += at(k);
      for (long k = n + 1; k <= r; ++k) sum -= at(k);
      um.push_back(sum);
    }
    at(from);  // the first point's value must be there too
    return um;
  };
  CompensationTable t;
  t.axis_in_file = "A" + *axis;
  const double step_mm = static_cast<double>(interval_du) * kDetectionUnitUm / kUmPerMm;
  for (long n = first; n <= last; ++n) t.position.push_back(static_cast<double>(n - reference) * step_mm);
  t.up_um = absolute(first);
  if (parameter.count(3626)) {
    const double at_reference = static_cast<double>(need(3627)) * kDetectionUnitUm;
    t.down_um = absolute(need(3626));
    for (auto& v : t.down_um) v += at_reference;
  } else {
    t.down_um = t.up_um;
  }
  const std::size_t expected = static_cast<std::size_t>(last - first + 1) * (parameter.count(3626) ? 2 : 1);
  if (data.size() != expected)
    throw InputError(
        fmt::format("{}: {} compensation points given, the parameters need {}", source, data.size(), expected));
  const bool rotary = parameter.count(3625) > 0;
  if (rotary && std::abs(t.position.back() - t.position.front() -
                         static_cast<double>(need(3625)) * kDetectionUnitUm / kUmPerMm) > 1e-9) {
    throw InputError(fmt::format("{}: parameter 3625 (travel per rotation) is not the points' span", source));
  }
  return closedTable(t, rotary, source);
}

}  // namespace

ControllerFormat fanucFormat() {
  return {"fanuc",
          "FANUC pitch error compensation, parameters 3620-3627 and the pitch error data (incremental, detection "
          "units of 1 um)",
          {false, true},
          0,
          kDetectionUnitUm,
          writeFanuc,
          readFanuc};
}

}  // namespace mtcal::processing::format_text
