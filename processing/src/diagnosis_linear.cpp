// The candidate catalogue of linear positioning runs (ISO 230-2 targets): the baseline (the
// line's zero against a model, or the run's own error curve), the folds by repeat, the grid's
// aliased periods, and the named causes (backlash, drift, cyclic error, Abbe, scale,
// environmental compensation, thermal growth).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "diagnosis_internal.h"
#include "mtcal/error.h"
#include "mtcal/processing/bspline.h"
#include "mtcal/processing/diagnosis.h"
#include "mtcal/processing/error_model.h"
#include "mtcal/processing/number_text.h"

namespace mtcal::processing {

using detail::addChannels;
using detail::candidate;
using detail::checkSizes;
using detail::distinct;
using detail::firstOrderDrift;
using detail::foldsByBlocks;
using detail::linearDrift;
using detail::mean;
using detail::shape;
using detail::varies;
using detail::vec;

namespace {

/// Apparent displacement per mm of uncompensated dead path and K of air temperature (um):
/// the air index falls by 0.929 ppm/K near 20 degC, 101.3 kPa (Edlen).
constexpr double kDeadPathUmPerMmK = 0.929e-3;
/// Optics further off the line than this are a set-up no one makes: a fit asking for more is
/// another cause with the same shape.
constexpr double kMaxAbbeOffsetMm = 500.0;
constexpr double kMaxDeadPathMm = 3000.0;
/// A wrong pressure compensation is at worst one of the sign reversed: twice the air index's
/// sensitivity (0.268 ppm/hPa near 101.3 kPa, Edlen); nothing else in a reading follows the
/// pressure. A fit asking for more is another cause whose course the pressure's resembles. (The
/// air's temperature has no such limit: a material sensor left in the air makes the expansion's
/// compensation follow it, 11.5 ppm/K for steel.)
constexpr double kMaxAirPressureCoefficientPpmPerHpa = 2.0 * 0.268;

/// A smooth course in time (a cubic B-spline of `spans` spans; 1: a cubic polynomial), times
/// the position for the terms proportional to it: what a channel that follows such a course
/// could be mistaken for, with as much freedom as the candidate has.
std::vector<ExtensionShape> smoothInTime(const DiagnosisData& d, bool times_position, int spans = 1) {
  if (!varies(d, "time_s")) return {};
  const auto& t = d.variable("time_s")->values;
  ExtensionShape s{times_position ? "spline*position_mm" : "spline", {"time_s"}};
  s.spans = spans;
  s.range = {t.minCoeff(), t.maxCoeff()};
  return {s};
}

}  // namespace

std::vector<double> aliasedPeriods(const std::vector<double>& positions_mm, double shortest_mm) {
  Eigen::VectorXd p = vec(positions_mm);
  const auto sites = distinct(p);
  if (sites.size() < 3) return {};
  double spacing = std::numeric_limits<double>::infinity();
  for (std::size_t i = 1; i < sites.size(); ++i) spacing = std::min(spacing, sites[i] - sites[i - 1]);
  for (double s : sites) {
    const double k = (s - sites.front()) / spacing;
    if (std::abs(k - std::round(k)) > 1e-6) return {};
  }
  std::vector<double> periods;
  for (int k = 1; spacing / k >= shortest_mm - 1e-12; ++k) periods.push_back(spacing / k);
  return periods;
}

namespace {

/// A grid that every distinct position but a few is on (a plan's nodes and its end point off
/// them): its spacing, the most common one between neighbours, and the positions off it. None
/// where every position is on it, or where more than a tenth of them (at least one) are off.
struct NearGrid {
  double spacing_mm = 0.0;
  std::vector<double> off_mm;
};
std::optional<NearGrid> nearGrid(const std::vector<double>& sites) {
  if (sites.size() < 8) return std::nullopt;
  std::map<long long, int> gaps;  // in nanometres
  for (std::size_t i = 1; i < sites.size(); ++i) ++gaps[std::llround(1e6 * (sites[i] - sites[i - 1]))];
  const auto common =
      std::max_element(gaps.begin(), gaps.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
  const double spacing = 1e-6 * static_cast<double>(common->first);
  if (!(spacing > 0.0)) return std::nullopt;
  const std::size_t most_off = std::max<std::size_t>(1, sites.size() / 10);
  std::optional<NearGrid> best;
  for (std::size_t a = 0; a <= most_off && a < sites.size(); ++a) {  // anchored on a position on the grid
    NearGrid g{spacing, {}};
    for (double s : sites) {
      const double k = (s - sites[a]) / spacing;
      if (std::abs(k - std::round(k)) > 1e-6) g.off_mm.push_back(s);
    }
    if (!best || g.off_mm.size() < best->off_mm.size()) best = std::move(g);
  }
  if (best->off_mm.empty() || best->off_mm.size() > most_off) return std::nullopt;
  return best;
}

}  // namespace

LinearErrorKind linearErrorKind(const std::string& measures) {
  const bool named = measures.size() == 3 && measures[0] == 'E' &&
                     std::string("XYZABC").find(measures[1]) != std::string::npos &&
                     std::string("XYZ").find(measures[2]) != std::string::npos;
  if (!named) throw InputError(fmt::format("'{}' is not an error of a linear axis (EXX, EYX, ECX ...)", measures));
  return {measures[1] == measures[2], measures[1] >= 'A' && measures[1] <= 'C'};
}

DiagnosisData linearDiagnosisData(const LinearRunInput& in) {
  const std::size_t n = in.position_mm.size();
  checkSizes(n, {in.deviation_um.size(), in.direction.size(), in.cycle.size()}, in.source);
  if (!in.time_s.empty() && in.time_s.size() != n)
    throw InputError(fmt::format("{}: {} times for {} points", in.source, in.time_s.size(), n));
  if (!in.simulated_um.empty() && in.simulated_um.size() != n)
    throw InputError(fmt::format("{}: {} predictions for {} points", in.source, in.simulated_um.size(), n));
  if (in.simulated_error_factor_um.size() &&
      (in.simulated_um.empty() || in.simulated_error_factor_um.rows() != static_cast<Eigen::Index>(n) ||
       !in.simulated_error_factor_um.allFinite()))
    throw InputError(fmt::format("{}: the model's stated error has {} rows for {} predictions{}", in.source,
                                 in.simulated_error_factor_um.rows(), in.simulated_um.size(),
                                 in.simulated_error_factor_um.allFinite() ? "" : ", or a value missing"));
  // A positioning error (EXX, or not said) has every cause of the catalogue; a straightness or an
  // angle the causes of any reading along a line (a reversal, a drift, a periodic error, a channel).
  const LinearErrorKind error = in.measures.empty() ? LinearErrorKind{true, false} : linearErrorKind(in.measures);
  const bool positioning = error.positioning, angle = error.angle;
  DiagnosisData d;
  d.kind = "linear";
  d.source = in.source;
  d.measures = in.measures;
  d.main_variable = "position_mm";
  d.value_unit = angle ? "urad" : "um";
  d.measured = vec(in.deviation_um);
  const bool has_model = !in.simulated_um.empty();
  d.simulated = has_model ? vec(in.simulated_um) : Eigen::VectorXd::Zero(static_cast<Eigen::Index>(n));
  d.model_description = has_model ? in.model_description : "none";
  const Eigen::VectorXd x = vec(in.position_mm);
  Eigen::VectorXd dir(static_cast<Eigen::Index>(n)), cyc(dir.size());
  for (std::size_t i = 0; i < n; ++i) {
    if (in.direction[i] != 1 && in.direction[i] != -1)
      throw InputError(fmt::format("{}: point {}: direction {} (must be +1 or -1)", in.source, i + 1, in.direction[i]));
    dir(static_cast<Eigen::Index>(i)) = in.direction[i];
    cyc(static_cast<Eigen::Index>(i)) = in.cycle[i];
  }
  d.variables = {{"position_mm", "mm", x}, {"direction", "", dir}, {"cycle", "", cyc}};
  // A time some points lack is not used (a drift needs every point's), and the notes say so.
  const auto missing_times =
      std::count_if(in.time_s.begin(), in.time_s.end(), [](double t) { return !std::isfinite(t); });
  const bool timed = !in.time_s.empty() && missing_times == 0;
  if (timed) d.variables.push_back({"time_s", "s", vec(in.time_s)});
  if (missing_times > 0)
    d.notes.push_back(
        fmt::format("time_s lacks {} of its {} values: not used (a drift needs every point's time)", missing_times, n));
  addChannels(d, in.channels, n, "channel");
  for (const auto& a : in.model_angles_urad) d.variables.push_back(a);

  // Baseline: the line's zero against a model; without one the run's own error curve,
  // averaged over both directions, knots no closer than min_knot_spacing_mm.
  const auto sites = distinct(x);
  const auto aliased = aliasedPeriods(in.position_mm);
  double knot_spacing_mm = in.min_knot_spacing_mm;
  if (has_model) {
    d.baseline = Eigen::MatrixXd::Ones(static_cast<Eigen::Index>(n), 1);
    d.baseline_description = "the model with the line's zero free";  // the model line names it
  } else {
    if (sites.size() < 2) throw InputError(fmt::format("{}: every point at one position: no error curve", in.source));
    const int degree = std::min<int>(3, static_cast<int>(sites.size()) - 1);
    auto knots = errorCurveKnots(sites, degree, knot_spacing_mm);
    // Positions off a grid (random offsets) see what varies faster than the curve (a lead
    // error) only if the curve leaves them room: at most one coefficient for two positions.
    // On a grid nothing between the positions can be seen, and the curve keeps its knots.
    const auto coefficients = [&] { return knots.size() - static_cast<std::size_t>(degree) - 1; };
    while (aliased.empty() && sites.size() >= 8 && 2 * coefficients() > sites.size()) {
      knot_spacing_mm *= 1.25;
      knots = errorCurveKnots(sites, degree, knot_spacing_mm);
    }
    const BSpline spline(degree, knots, Eigen::VectorXd::Zero(static_cast<Eigen::Index>(knots.size()) - degree - 1));
    d.baseline.resize(static_cast<Eigen::Index>(n), spline.coefficients().size());
    for (std::size_t i = 0; i < n; ++i)
      d.baseline.row(static_cast<Eigen::Index>(i)) = spline.basis(in.position_mm[i]).transpose();
    d.baseline_description = fmt::format(
        "the run's own error curve averaged over both directions: cubic B-spline, {} coefficients for {} positions "
        "(knots at least {} mm apart)",
        spline.coefficients().size(), sites.size(),
        knot_spacing_mm == std::round(knot_spacing_mm) ? fmt::format("{:.0f}", knot_spacing_mm)
                                                       : significant(knot_spacing_mm, 3));
    // Knots asked so far apart that the travel holds one span (more than half of it).
    if (const double travel_mm = sites.back() - sites.front();
        spline.coefficients().size() == degree + 1 && in.min_knot_spacing_mm > travel_mm / 2.0) {
      d.warnings.push_back(fmt::format(
          "knots at least {:g} mm apart leave one span on the travel of {:g} mm: the run's own error curve is one "
          "cubic, and what the axis' error has beyond a cubic is left to be named as causes",
          in.min_knot_spacing_mm, travel_mm));
    }
    if (static_cast<std::size_t>(spline.coefficients().size()) >= sites.size()) {
      d.notes.push_back(
          "the baseline passes through the mean of every position: structure between the positions (a cyclic error "
          "shorter than the spacing) shows only in a run that measures other positions");
    }
  }
  d.site.resize(static_cast<Eigen::Index>(n));
  for (std::size_t i = 0; i < n; ++i) {
    d.site(static_cast<Eigen::Index>(i)) =
        static_cast<int>(std::lower_bound(sites.begin(), sites.end(), in.position_mm[i] - 1e-9) - sites.begin());
  }
  if (has_model && in.simulated_error_factor_um.size()) {  // a site's row: its first reading's
    d.model_error_factor.setZero(static_cast<Eigen::Index>(sites.size()), in.simulated_error_factor_um.cols());
    for (Eigen::Index i = static_cast<Eigen::Index>(n) - 1; i >= 0; --i)
      d.model_error_factor.row(d.site(i)) = in.simulated_error_factor_um.row(i);
  }
  // Folds: the repeats; a single repeat is split into blocks of time (or of the order).
  std::set<int> cycles(in.cycle.begin(), in.cycle.end());
  d.fold.resize(static_cast<Eigen::Index>(n));
  if (cycles.size() >= 2) {
    // More than kMaxFolds cycles are left out in groups of consecutive cycles: the held-out
    // test stays by whole repeats, its cost does not grow with the number of repeats.
    constexpr std::size_t kMaxFolds = 10;
    const std::size_t folds = std::min(cycles.size(), kMaxFolds);
    std::vector<int> order(cycles.begin(), cycles.end());
    for (std::size_t i = 0; i < n; ++i) {
      const auto rank =
          static_cast<std::size_t>(std::lower_bound(order.begin(), order.end(), in.cycle[i]) - order.begin());
      d.fold(static_cast<Eigen::Index>(i)) = static_cast<int>(rank * folds / cycles.size());
    }
    d.fold_description =
        folds == cycles.size()
            ? fmt::format("by repeat: each of the {} cycles left out in turn", cycles.size())
            : fmt::format("by repeat: the {} cycles left out in {} groups of consecutive cycles", cycles.size(), folds);
  } else {
    Eigen::VectorXd order =
        !timed ? Eigen::VectorXd::LinSpaced(static_cast<Eigen::Index>(n), 0, static_cast<double>(n - 1))
               : vec(in.time_s);
    d.fold = foldsByBlocks(order, 4);
    d.fold_description = "one repeat: four contiguous blocks in time order, each left out in turn";
  }
  // On a grid of spacing s only periods from 2 s up are distinct: shorter ones read as one of them.
  if (const auto& periods = aliased; !periods.empty()) {
    std::string list;
    for (std::size_t k = 0; k < std::min<std::size_t>(periods.size(), 4); ++k)
      list += fmt::format("{}{:.4g}", k ? ", " : "", periods[k]);
    d.warnings.push_back(
        fmt::format("every target is on a {:.4g} mm grid: a cyclic error of period {} mm (or any {:.4g} mm / k) reads "
                    "the same at every target "
                    "and cannot be seen, and any other period reads as its alias longer than {:.4g} mm; measure a plan "
                    "with random target "
                    "offsets or a finer validation run (e.g. every ~3 mm)",
                    periods.front(), list, periods.front(), 2.0 * periods.front()));
  }
  // Nearly on a coarser grid: its periods differ at the few positions off it only.
  if (const auto near = nearGrid(sites); near && (aliased.empty() || near->spacing_mm > aliased.front() + 1e-9)) {
    std::vector<std::string> off, periods;
    for (double s : near->off_mm) off.push_back(fmt::format("{:g}", s));
    // A period every target is on a grid of (the finer grid's, said above) is not seen at all.
    const auto everySiteOnGrid = [&](double period_mm) {
      return std::all_of(sites.begin(), sites.end(), [&](double s) {
        const double k = (s - sites.front()) / period_mm;
        return std::abs(k - std::round(k)) <= 1e-6;
      });
    };
    for (int k = 1; k <= 12 && periods.size() < 3; ++k)
      if (!everySiteOnGrid(near->spacing_mm / k)) periods.push_back(fmt::format("{:.4g}", near->spacing_mm / k));
    d.warnings.push_back(fmt::format(
        "every target but {} mm is on a {:g} mm grid: a cyclic error of period {} mm (or another {:g} mm / k{}) "
        "differs only at {}, and is hardly seen",
        fmt::join(off, ", "), near->spacing_mm, fmt::join(periods, ", "), near->spacing_mm,
        aliased.empty() ? "" : fmt::format(" the {:.4g} mm grid does not hide", aliased.front()),
        off.size() == 1 ? "that target" : "those targets"));
  }

  // Candidate causes.
  const double mid = 0.5 * (x.minCoeff() + x.maxCoeff());
  const double length = std::max(1e-9, x.maxCoeff() - x.minCoeff());
  // A positioning run's reversal (ISO 230-2: the mean up less the mean down) is minus its drive's
  // lost motion: the axis stops short of a target by half of it, in the approach's direction.
  d.candidates.push_back(candidate(
      "backlash", "direction",
      positioning ? std::string("reversal error: lost motion of the drive between the two approach directions")
                  : fmt::format("reversal error: {} differs between the two approach directions (the carriage "
                                "turning or shifting in its guides as the drive reverses)",
                                in.measures),
      {shape("linear", {"direction"}, 0.5)}, {{"reversal", "um", 1.0}}));
  if (positioning && !in.measures.empty()) {  // the drive of the axis the run reads along itself
    auto& reversal = d.candidates.back().parameters.front();
    reversal.quantity = detail::lostMotion(in.measures.substr(2));
    reversal.per_quantity = -1.0;
  }
  d.candidates.push_back(candidate(
      "backlash", "direction",
      positioning ? "reversal error that changes along the travel (wear or a pitch of the screw varying with load)"
                  : "reversal error that changes along the travel",
      {shape("linear", {"direction"}, 0.5), shape("product", {"direction", "position_mm"}, 0.5 / length, mid)},
      {{"reversal", "um", 1.0}, {"reversal_change_over_travel", "um", 1.0}}));
  if (varies(d, "time_s")) {
    const auto& t = d.variable("time_s")->values;
    d.candidates.push_back(linearDrift());
    d.candidates.push_back(firstOrderDrift(t));
    if (positioning) {
      for (auto& c : detail::thermalGrowth(t)) d.candidates.push_back(std::move(c));
    }
  }
  // Cyclic error: periods between 2 mm and twice the knot spacing (longer ones the baseline
  // follows), searched evenly in frequency, three times finer than the run's span resolves.
  {
    // Longer periods are within what an error curve with knots this far apart represents:
    // a model's own identification error looks like them. Knots set wider than the default
    // (--knot-spacing-mm 100) leave more of the axis' own curve in the residual, which a sine
    // of two repeats fits: beyond the default's range, a period is searched only while it
    // repeats at least four times along the travel (a drive's periodic error repeats).
    const double longest =
        std::min(2.0 * knot_spacing_mm, std::max(length / 4.0, 2.0 * std::min(knot_spacing_mm, kDefaultKnotSpacingMm)));
    const double shortest = aliased.empty() ? 2.0 : 2.0 * aliased.front();
    if (longest > shortest) {
      auto c = candidate("cyclic_error", "position_mm",
                         "periodic error of the drive (screw lead, encoder or scale interpolation)",
                         {shape("harmonic", {"position_mm"})}, {{"sin", "um", 1.0}, {"cos", "um", 1.0}});
      if (!aliased.empty()) {
        c.cause += fmt::format(
            " (on the {:.4g} mm grid the period found may stand for any p with 1/p = 1/period + k/{:.4g} mm)",
            aliased.front(), aliased.front());
      }
      const double df = 1.0 / (3.0 * length);
      for (double f = 1.0 / longest; f <= 1.0 / shortest; f += df) c.search.push_back(1.0 / f);
      c.independent_tries = std::max(1.0, c.search.size() / 3.0);
      c.shapes.front().searched = c.search.front();
      c.searched_name = "period";
      c.searched_unit = "mm";
      d.candidates.push_back(c);
    }
  }
  // What only a positioning reading has: the optics' offset turning an angle into it, its scale,
  // the air's compensation of the wavelength, the axis' growth with the machine's temperature.
  const auto positioning_causes_from = d.candidates.size();
  for (const auto& a : in.model_angles_urad) {
    if (!varies(d, a.name)) continue;
    d.candidates.push_back(
        candidate("abbe_error", a.name,
                  fmt::format("Abbe error: the optics sit off the line the model assumes, so the angular error {} adds "
                              "offset x angle",
                              a.name),
                  {shape("linear", {a.name}, 1e-3)}, {{"offset", "mm", 1.0, kMaxAbbeOffsetMm}}));
  }
  if (has_model) {
    d.candidates.push_back(candidate(
        "scale_error", "position_mm",
        "error proportional to position: scale (linear expansion, encoder pitch) or cosine misalignment of the optics",
        {shape("linear", {"position_mm"}, 1e-3, x.minCoeff())}, {{"scale", "ppm", 1.0}}));
  }
  for (const auto& [name, unit, per, parameter, max_abs] :
       {std::tuple{"air_temp_c", "ppm/K", 1.0, "air_temp_coefficient", 0.0},
        std::tuple{"air_pressure_pa", "ppm/hPa", 100.0, "air_pressure_coefficient",
                   kMaxAirPressureCoefficientPpmPerHpa}}) {
    if (!varies(d, name)) continue;
    const double ref = mean(d.variable(name)->values);
    d.candidates.push_back(candidate(
        "environment_compensation", name,
        fmt::format("wrong environmental compensation: an error proportional to position and to the change of {}",
                    name),
        {shape("product", {"position_mm", name}, 1e-3 / per, ref)}, {{parameter, unit, 1.0, max_abs}}));
  }
  if (varies(d, "air_temp_c")) {
    d.candidates.push_back(candidate(
        "environment_compensation", "air_temp_c",
        "dead path: the beam between the interferometer and the datum is not compensated for the air's change",
        {shape("linear", {"air_temp_c"}, kDeadPathUmPerMmK, mean(d.variable("air_temp_c")->values))},
        {{"dead_path", "mm", 1.0, kMaxDeadPathMm}}));
    d.candidates.back().confounders = smoothInTime(d, false);
  }
  if (varies(d, "material_temp_c")) {
    d.candidates.push_back(candidate(
        "thermal_growth", "material_temp_c",
        "thermal growth of the axis with the machine's temperature (expansion not, or wrongly, compensated)",
        {shape("product", {"position_mm", "material_temp_c"}, 1e-3, mean(d.variable("material_temp_c")->values))},
        {{"expansion_error", "ppm/K", 1.0}}));
    d.candidates.back().confounders = smoothInTime(d, true);
  }
  if (!positioning) {
    d.candidates.erase(d.candidates.begin() + static_cast<std::ptrdiff_t>(positioning_causes_from), d.candidates.end());
  }
  // The reading following an auxiliary quantity (a coolant's temperature, a hydraulic
  // pressure, the machine's temperature): linear in it, or a smooth curve of it. The air's
  // temperature has its physics above (the dead path) in a positioning run; in a straightness's
  // or an angle's it is a channel as the others.
  for (const auto& channel : in.channels) {
    if ((channel.name == "air_temp_c" && positioning) || !varies(d, channel.name)) continue;
    const auto& values = d.variable(channel.name)->values;
    const std::string cause = fmt::format("the reading follows {}", channel.name);
    const std::string per_unit = channel.unit.empty() ? "um" : "um/" + channel.unit;
    d.candidates.push_back(candidate("channel_dependence", channel.name, cause + " (linearly)",
                                     {shape("linear", {channel.name}, 1.0, mean(values))},
                                     {{"sensitivity", per_unit, 1.0}}));
    d.candidates.back().confounders = smoothInTime(d, false);
    if (const auto known = distinct(values); known.size() >= 12) {
      // A curve: the sensitivity changing along the channel (a quadratic about its mean, held
      // within the range it was fitted over). A channel that wanders leaves a repeat held out at
      // the edge of its range, where a cubic fitted on the other repeats extrapolates wildly (a
      // spline of four spans took 157 um held out where the effect was 2.3 um RMS; a cubic,
      // 7.4 um where it was 1.8 um).
      auto curve = shape("quadratic", {channel.name}, 1.0, mean(values));
      curve.range = {known.front(), known.back()};
      d.candidates.push_back(
          candidate("channel_dependence", channel.name, cause + " (a smooth curve of it)", {curve}, {}));
      d.candidates.back().confounders = smoothInTime(d, false);
    }
  }
  const std::string between_positions =
      "what changes between measured positions faster than their spacing shows only as scatter or an alias";
  d.notes.push_back(positioning ? "one line's readings along it cannot see its errors across the line (straightness) "
                                  "nor its angles, except as an Abbe offset turns them into the reading; " +
                                      between_positions
                                : fmt::format("a run of {} reads that error alone: the line's other errors are "
                                              "other runs'; {}",
                                              in.measures, between_positions));
  // A straightness in um, an angle in urad: the parameters in the reading's unit (um/h: urad/h).
  if (d.value_unit != "um") {
    for (auto& c : d.candidates) {
      for (auto& parameter : c.parameters) {
        if (parameter.unit.rfind("um", 0) == 0) parameter.unit = d.value_unit + parameter.unit.substr(2);
      }
    }
  }
  return d;
}

}  // namespace mtcal::processing
