#include "mtcal/acquisition/linear_plan.h"

#include <fmt/format.h>

#include <cmath>
#include <fstream>
#include <random>
#include <set>
#include <sstream>

#include "mtcal/acquisition/csv.h"
#include "mtcal/acquisition/gcode.h"
#include "mtcal/error.h"
#include "mtcal/processing/diagnosis.h"
#include "plan_json.h"

namespace mtcal::acquisition {
using plan_json::bad;
using plan_json::kMaxMachineCoordinateMm;
using plan_json::nonNegative;
using plan_json::pointMm;
using plan_json::positive;
using plan_json::read;

std::map<std::string, double> parseLinePosition(const nlohmann::json& line, const std::string& source) {
  if (!line.is_object()) bad(source, "line_position_mm", "must be an object of axis names to mm, e.g. {\"Y\": 100}");
  std::map<std::string, double> out;
  for (const auto& [axis, value] : line.items()) {
    if (axis != "X" && axis != "Y" && axis != "Z") bad(source, "line_position_mm." + axis, "not an axis (X, Y, Z)");
    if (!value.is_number() || !std::isfinite(value.get<double>())) {
      bad(source, "line_position_mm." + axis, "must be a number (mm)");
    }
    // A machine coordinate: within 100 m of the origin, as a point's (a value beyond is in um).
    if (std::abs(value.get<double>()) > kMaxMachineCoordinateMm)
      bad(source, "line_position_mm." + axis,
          fmt::format("{:g} mm is beyond {:g} m of the origin (mm, not um)", value.get<double>(),
                      kMaxMachineCoordinateMm / 1000.0));
    out[axis] = value.get<double>();
  }
  return out;
}

LinearPlan LinearPlan::fromJson(const nlohmann::json& j, const std::string& source) {
  plan_json::checkTypeAndKeys(j, source, "linear");
  LinearPlan p;
  read(j, "name", p.name, source);
  read(j, "axis", p.axis, source);
  read(j, "start_mm", p.start_mm, source);
  read(j, "end_mm", p.end_mm, source);
  read(j, "step_mm", p.step_mm, source);
  read(j, "repeats", p.repeats, source);
  read(j, "bidirectional", p.bidirectional, source);
  read(j, "overrun_mm", p.overrun_mm, source);
  read(j, "dwell_s", p.dwell_s, source);
  read(j, "window_s", p.window_s, source);
  read(j, "sample_rate_hz", p.sample_rate_hz, source);
  read(j, "stability_threshold_um", p.stability_threshold_um, source);
  read(j, "stability_timeout_s", p.stability_timeout_s, source);
  read(j, "random_offset_mm", p.random_offset_mm, source);
  read(j, "random_seed", p.random_seed, source);
  p.datum_mm = p.start_mm;
  read(j, "datum_mm", p.datum_mm, source);
  read(j, "expansion_per_k", p.expansion_per_k, source);
  read(j, "air_index_model", p.air_index_model, source);
  read(j, "co2_ppm", p.co2_ppm, source);
  read(j, "feed_mm_min", p.feed_mm_min, source);
  read(j, "gcode_dialect", p.gcode_dialect, source);
  read(j, "trigger_timeout_s", p.trigger_timeout_s, source);
  read(j, "measures", p.measures, source);
  if (j.contains("line_position_mm")) p.line_position_mm = parseLinePosition(j["line_position_mm"], source);
  if (j.contains("reflector_offset_mm")) {
    const auto r = pointMm(j["reflector_offset_mm"], source, "reflector_offset_mm", 1e4, "the tool point");
    for (int i = 0; i < 3; ++i) p.reflector_offset_mm[static_cast<std::size_t>(i)] = r(i);
  }

  if (p.axis != "X" && p.axis != "Y" && p.axis != "Z")
    bad(source, "axis", fmt::format("'{}' is not an axis: must be X, Y or Z", p.axis));
  if (p.line_position_mm.count(p.axis)) bad(source, "line_position_mm." + p.axis, "is the measured axis");
  if (!(p.end_mm > p.start_mm)) bad(source, "end_mm", "must be greater than start_mm");
  if (!(std::abs(p.datum_mm) <= plan_json::kMaxMachineCoordinateMm))
    bad(source, "datum_mm",
        fmt::format("must be a machine coordinate within {:g} m of the origin (mm), got {}",
                    plan_json::kMaxMachineCoordinateMm / 1000.0, p.datum_mm));
  positive(p.step_mm, source, "step_mm");
  if (p.step_mm > p.end_mm - p.start_mm) bad(source, "step_mm", "is larger than the measured range");
  if ((p.end_mm - p.start_mm) / p.step_mm > 10000) bad(source, "step_mm", "gives more than 10000 targets");
  if (p.repeats < 2 || p.repeats > 1000)
    bad(source, "repeats", "must be 2..1000 (at least 2 to estimate repeatability; ISO 230-2 takes 5)");
  nonNegative(p.overrun_mm, source, "overrun_mm");
  nonNegative(p.dwell_s, source, "dwell_s");
  positive(p.window_s, source, "window_s");
  if (p.sample_rate_hz < 1 || p.sample_rate_hz > 50000) bad(source, "sample_rate_hz", "must be 1..50000");
  if (p.window_s * p.sample_rate_hz < 2) bad(source, "window_s", "holds fewer than 2 samples at sample_rate_hz");
  positive(p.stability_threshold_um, source, "stability_threshold_um");
  positive(p.stability_timeout_s, source, "stability_timeout_s");
  nonNegative(p.random_offset_mm, source, "random_offset_mm");
  if (p.random_offset_mm >= p.step_mm / 2) bad(source, "random_offset_mm", "must be less than half the step");
  if (!(p.expansion_per_k >= 0.0 && p.expansion_per_k < 1e-4)) {
    bad(source, "expansion_per_k", "must be in [0, 1e-4) 1/K (steel is about 11.5e-6)");
  }
  if (p.air_index_model != "edlen" && p.air_index_model != "ciddor")
    bad(source, "air_index_model", "must be edlen or ciddor");
  if (!(p.co2_ppm >= 0.0 && p.co2_ppm <= 2000.0)) bad(source, "co2_ppm", "must be 0..2000");
  positive(p.feed_mm_min, source, "feed_mm_min");
  if (p.gcode_dialect != "iso" && p.gcode_dialect != "fanuc") bad(source, "gcode_dialect", "must be iso or fanuc");
  positive(p.trigger_timeout_s, source, "trigger_timeout_s");
  try {
    measuredComponent(p);
  } catch (const InputError& e) {
    bad(source, "measures", e.what());
  }
  return p;
}

LinearPlan LinearPlan::load(const std::string& path) { return fromJson(readJsonFile(path), path); }

nlohmann::json LinearPlan::toJson() const {
  return {{"type", "linear"},
          {"name", name},
          {"axis", axis},
          {"start_mm", start_mm},
          {"end_mm", end_mm},
          {"step_mm", step_mm},
          {"repeats", repeats},
          {"bidirectional", bidirectional},
          {"overrun_mm", overrun_mm},
          {"dwell_s", dwell_s},
          {"window_s", window_s},
          {"sample_rate_hz", sample_rate_hz},
          {"stability_threshold_um", stability_threshold_um},
          {"stability_timeout_s", stability_timeout_s},
          {"random_offset_mm", random_offset_mm},
          {"random_seed", random_seed},
          {"datum_mm", datum_mm},
          {"expansion_per_k", expansion_per_k},
          {"air_index_model", air_index_model},
          {"co2_ppm", co2_ppm},
          {"feed_mm_min", feed_mm_min},
          {"gcode_dialect", gcode_dialect},
          {"trigger_timeout_s", trigger_timeout_s},
          {"measures", measuredError(*this)},
          {"line_position_mm", line_position_mm},
          {"reflector_offset_mm", reflector_offset_mm}};
}

LinearPlan LinearPlan::demo() {
  LinearPlan p;
  p.name = "X axis positioning, 50-600 mm, 20 mm nodes, 9 cycles";
  p.reflector_offset_mm = {0.0, 25.0, 45.0};  // as a reflector clamped beside the tool sits: Abbe arms
  return p;
}

std::vector<double> LinearPlan::targetPositions() const {
  std::vector<double> targets;
  const auto steps = static_cast<int>(std::floor((end_mm - start_mm) / step_mm + 1e-9));
  for (int i = 0; i <= steps; ++i) targets.push_back(start_mm + i * step_mm);
  if (end_mm - targets.back() > 1e-6) targets.push_back(end_mm);
  if (random_offset_mm > 0.0) {
    // The same random component for a target in every cycle (ISO 230-2 5.3.2); the ends stay.
    std::mt19937_64 rng(random_seed);
    std::uniform_real_distribution<double> offset(-random_offset_mm, random_offset_mm);
    for (std::size_t i = 1; i + 1 < targets.size(); ++i) targets[i] += offset(rng);
  }
  return targets;
}

std::string measuredError(const LinearPlan& plan) {
  return plan.measures.empty() ? "E" + plan.axis + plan.axis : plan.measures;
}

int measuredComponent(const LinearPlan& plan) {
  const std::string name = measuredError(plan);
  static const std::string kLetters = "XYZABC";
  if (name.size() != 3 || name[0] != 'E' || name.substr(2) != plan.axis ||
      kLetters.find(name[1]) == std::string::npos) {
    throw InputError("'" + name + "' is not one of the errors of axis " + plan.axis + " (E" + "X" + plan.axis + ", E" +
                     "Y" + plan.axis + ", E" + "Z" + plan.axis + ", E" + "A" + plan.axis + ", E" + "B" + plan.axis +
                     ", E" + "C" + plan.axis + ")");
  }
  return static_cast<int>(kLetters.find(name[1]));
}

bool measuresPositioning(const LinearPlan& plan) {
  measuredComponent(plan);  // an error of the plan's axis, or refused with the errors it has
  return processing::linearErrorKind(measuredError(plan)).positioning;
}

double triggerToleranceMm(const LinearPlan& plan) {
  const auto targets = plan.targetPositions();
  double gap = plan.step_mm;
  for (std::size_t i = 1; i < targets.size(); ++i) gap = std::min(gap, targets[i] - targets[i - 1]);
  if (plan.overrun_mm > 0.0) gap = std::min(gap, plan.overrun_mm);
  return gap / 4.0;
}

std::vector<PlannedMove> linearMoves(const LinearPlan& plan) {
  const std::vector<double> targets = plan.targetPositions();
  std::vector<PlannedMove> moves;
  std::int64_t seq = 0;
  for (int cycle = 1; cycle <= plan.repeats; ++cycle) {
    moves.push_back({targets.front() - plan.overrun_mm, false, {}});
    for (double t : targets) moves.push_back({t, true, {seq++, t, +1, cycle}});
    if (plan.bidirectional) {
      moves.push_back({targets.back() + plan.overrun_mm, false, {}});
      for (auto it = targets.rbegin(); it != targets.rend(); ++it)
        moves.push_back({*it, true, {seq++, *it, -1, cycle}});
    }
  }
  return moves;
}

std::vector<PlannedTarget> linearTargets(const LinearPlan& plan) {
  std::vector<PlannedTarget> out;
  for (const auto& m : linearMoves(plan)) {
    if (m.capture) out.push_back(m.target);
  }
  return out;
}

std::string linearGcode(const LinearPlan& plan) {
  std::ostringstream g;
  // mtcal recognises a hold after a dwell of stable readings, then waits the dwell and
  // averages a window: the program holds for both dwells, two windows and a second of margin.
  const double hold_s = 2.0 * plan.dwell_s + 2.0 * plan.window_s + 1.0;
  const std::string dwell = gcodeDwell(plan.gcode_dialect, hold_s);
  g << "%\n";
  g << fmt::format("(mtcal linear positioning plan: {})\n", gcodeCommentText(plan.name));
  g << fmt::format("({} axis, {} to {} mm, step {} mm, {} cycles, {})\n", plan.axis, plan.start_mm, plan.end_mm,
                   plan.step_mm, plan.repeats, plan.bidirectional ? "bidirectional" : "unidirectional");
  g << fmt::format("(each target is held {:.3f} s: mtcal sees the hold, waits the dwell, averages)\n", hold_s);
  g << "(mtcal captures a target when the laser reading is stable)\n";
  g << gcodeDwellComment(plan.gcode_dialect);
  g << "G21 G90 G94\n";
  for (const auto& [axis, position_mm] : plan.line_position_mm) {
    g << fmt::format("G1 {}{:.4f} F{:.0f} (the measured line)\n", axis, position_mm, plan.feed_mm_min);
  }
  g << fmt::format("G1 {}{:.4f} F{:.0f} (approach the datum from below)\n", plan.axis, plan.datum_mm - plan.overrun_mm,
                   plan.feed_mm_min);
  g << fmt::format("G1 {}{:.4f}\n", plan.axis, plan.datum_mm);
  g << fmt::format("{} (datum: the laser reading here is the zero)\n", dwell);
  for (const auto& m : linearMoves(plan)) {
    g << fmt::format("G1 {}{:.4f}", plan.axis, m.position_mm);
    if (m.capture) {
      g << fmt::format(" (target {} cycle {} {})\n", m.target.seq + 1, m.target.cycle,
                       m.target.direction > 0 ? "up" : "down");
      g << dwell << "\n";
    } else {
      g << " (overrun)\n";
    }
  }
  g << "M30\n%\n";
  return g.str();
}

}  // namespace mtcal::acquisition
