// Circular tests with a ballbar: run a plan on the simulated machine (mtcal run ballbar),
// import circle data (mtcal import circle), evaluate (mtcal analyze iso230-4) and diagnose
// (mtcal analyze ballbar) a stored test.

#include <fmt/format.h>

#include <cmath>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "mtcal/acquisition/circle_test.h"
#include "mtcal/services/workshop.h"
#include "mtcal/services/version.h"
#include "mtcal/error.h"
#include "mtcal/processing/iso230_4.h"

namespace mtcal::app {
namespace {

struct StoredCircle {
  double radius_mm = 0.0, feed_mm_per_min = 1000.0;
  processing::Plane plane = processing::Plane::kXY;
  bool bar_zeroed = true;
  std::vector<processing::CirclePoint> points;
};

StoredCircle loadCircle(storage::Store& store, storage::Id run_id) {
  const auto info = store.run(run_id);
  if (info.kind != "circle") throw InputError(fmt::format("run {} is a {} run, not a circular test", run_id, info.kind));
  const auto plan = nlohmann::json::parse(info.plan_json);
  StoredCircle c;
  c.radius_mm = plan.at("radius_mm").get<double>();
  c.feed_mm_per_min = plan.value("feed_mm_per_min", 1000.0);
  c.plane = processing::parsePlane(plan.value("plane", "XY"));
  // Acquired tests say whether the bar was zeroed; imported data are taken as calibrated.
  c.bar_zeroed = !plan.contains("calibrator_length_mm") || !plan["calibrator_length_mm"].is_null();
  c.points = acquisition::toCirclePoints(store.circlePoints(run_id));
  if (c.points.empty()) throw InputError(fmt::format("run {} has no circle points stored", run_id));
  return c;
}

// Plane axis letters in lower case: XY -> x, y; YZ -> y, z; ZX -> z, x.
std::pair<std::string, std::string> axisLetters(processing::Plane plane) {
  const auto a = processing::planeAxes(plane);
  const char* names = "xyz";
  return {std::string(1, names[a.first]), std::string(1, names[a.second])};
}

nlohmann::json optionalNumber(const std::optional<double>& v) { return v ? nlohmann::json(*v) : nlohmann::json(nullptr); }

std::string shown(const std::optional<double>& v, const char* unit) {
  return v ? fmt::format("{:.3f} {}", *v, unit) : std::string("not detected");
}

nlohmann::json iso230_4Json(const StoredCircle& c, const processing::CircularTestResult& r) {
  const auto [first, second] = axisLetters(c.plane);
  nlohmann::json j{{"plane", processing::planeName(c.plane)},
                   {"radius_mm", c.radius_mm},
                   {"feed_mm_per_min", c.feed_mm_per_min},
                   {"G_ccw_um", r.ccw ? nlohmann::json(r.ccw->g_um) : nlohmann::json(nullptr)},
                   {"G_cw_um", r.cw ? nlohmann::json(r.cw->g_um) : nlohmann::json(nullptr)},
                   {"G_um", r.g_b_um ? *r.g_b_um : (r.ccw ? r.ccw->g_um : r.cw->g_um)},
                   {"H_um", optionalNumber(r.h_um)},
                   {"centre_" + first + "_um", r.centre_first_um},
                   {"centre_" + second + "_um", r.centre_second_um}};
  for (const auto& [path, name] : {std::pair{&r.ccw, "ccw"}, std::pair{&r.cw, "cw"}}) {
    if (!*path) continue;
    const auto& p = **path;
    j[name] = {{"points", p.points},
               {"angle_span_deg", p.angle_span_deg},
               {"G_um", p.g_um},
               {"radius_deviation_um", p.radius_deviation_um},
               {"centre_" + first + "_um", p.centre_first_um},
               {"centre_" + second + "_um", p.centre_second_um},
               {"rms_um", p.rms_um}};
  }
  return j;
}

nlohmann::json diagnosisJson(const StoredCircle& c, const processing::BallbarDiagnosis& d) {
  const auto [first, second] = axisLetters(c.plane);
  const std::string cyclic_axis = d.cyclic_axis == 0 ? first : d.cyclic_axis == 1 ? second : "";
  return {{"squareness_urad", optionalNumber(d.squareness_urad)},
          {"servo_mismatch_ms", optionalNumber(d.servo_mismatch_ms)},
          {"scale_mismatch_" + first + "_ppm", optionalNumber(d.scale_mismatch_first_ppm)},
          {"scale_mismatch_" + second + "_ppm", optionalNumber(d.scale_mismatch_second_ppm)},
          {"backlash_" + first + "_um", optionalNumber(d.backlash_first_um)},
          {"backlash_" + second + "_um", optionalNumber(d.backlash_second_um)},
          {"reversal_spike_" + first + "_um", optionalNumber(d.reversal_spike_first_um)},
          {"reversal_spike_" + second + "_um", optionalNumber(d.reversal_spike_second_um)},
          {"straightness_" + first + "_um", optionalNumber(d.straightness_first_um)},
          {"straightness_" + second + "_um", optionalNumber(d.straightness_second_um)},
          {"cyclic_amplitude_um", optionalNumber(d.cyclic_amplitude_um)},
          {"cyclic_period_mm", optionalNumber(d.cyclic_period_mm)},
          {"cyclic_axis", cyclic_axis.empty() ? nlohmann::json(nullptr) : nlohmann::json(cyclic_axis)}};
}

// Evaluates, stores the result and prints it (text, or JSON when `emit_json`). @return the JSON
nlohmann::json printIso230_4(const Globals& g, storage::Store& store, storage::Id run_id, const StoredCircle& c,
                             bool emit_json) {
  const auto r = processing::evaluateCircularTest(c.radius_mm, c.points);
  nlohmann::json j = iso230_4Json(c, r);
  store.addResult(run_id, "iso230-4", kVersion, "{}", j.dump());
  j["run_id"] = run_id;
  if (g.json) {
    if (emit_json) *g.out << j.dump() << "\n";
    return j;
  }
  const auto [first, second] = axisLetters(c.plane);
  *g.out << fmt::format("ISO 230-4 circular test, run {}: {} plane, radius {} mm, feed {} mm/min\n\n", run_id,
                        processing::planeName(c.plane), c.radius_mm, c.feed_mm_per_min);
  *g.out << "direction  points  span_deg    G_um  radius_dev_um  centre_um\n";
  for (const auto& [path, name] : {std::pair{&r.ccw, "ccw"}, std::pair{&r.cw, "cw"}}) {
    if (!*path) continue;
    const auto& p = **path;
    *g.out << fmt::format("{:<9} {:>7} {:>9.1f} {:>7.2f} {:>14.2f}  {}={:.2f} {}={:.2f}\n", name, p.points,
                          p.angle_span_deg, p.g_um, p.radius_deviation_um, first, p.centre_first_um, second,
                          p.centre_second_um);
  }
  if (r.g_b_um) *g.out << fmt::format("\nG(b) bidirectional circular deviation: {:.2f} um\n", *r.g_b_um);
  if (r.h_um) *g.out << fmt::format("H bidirectional circular hysteresis:    {:.2f} um\n", *r.h_um);
  return 0;
}

nlohmann::json printDiagnosis(const Globals& g, storage::Store& store, storage::Id run_id, const StoredCircle& c,
                              bool emit_json) {
  const auto d = processing::diagnoseBallbar(c.radius_mm, c.points, {c.feed_mm_per_min, c.bar_zeroed, 6.0});
  nlohmann::json j{{"plane", processing::planeName(c.plane)},
                   {"radius_mm", c.radius_mm},
                   {"feed_mm_per_min", c.feed_mm_per_min},
                   {"diagnosis", diagnosisJson(c, d)},
                   {"rms_before_um", d.rms_before_um},
                   {"rms_after_um", d.rms_after_um},
                   {"notes", d.notes}};
  store.addResult(run_id, "ballbar-diagnosis", kVersion, "{}", j.dump());
  j["run_id"] = run_id;
  if (g.json) {
    if (emit_json) *g.out << j.dump() << "\n";
    return j;
  }
  const auto [first, second] = axisLetters(c.plane);
  const auto F = [](std::string s) {
    for (auto& ch : s) ch = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
    return s;
  };
  *g.out << fmt::format("Ballbar diagnosis, run {}: {} plane, radius {} mm, feed {} mm/min\n\n", run_id,
                        processing::planeName(c.plane), c.radius_mm, c.feed_mm_per_min);
  *g.out << fmt::format("  squareness                {}\n", shown(d.squareness_urad, "urad"));
  *g.out << fmt::format("  servo mismatch            {}\n", shown(d.servo_mismatch_ms, "ms"));
  *g.out << fmt::format("  scale mismatch {}          {}\n", F(first), shown(d.scale_mismatch_first_ppm, "ppm"));
  *g.out << fmt::format("  scale mismatch {}          {}\n", F(second), shown(d.scale_mismatch_second_ppm, "ppm"));
  *g.out << fmt::format("  backlash {}                {}\n", F(first), shown(d.backlash_first_um, "um"));
  *g.out << fmt::format("  backlash {}                {}\n", F(second), shown(d.backlash_second_um, "um"));
  *g.out << fmt::format("  reversal spike {}          {}\n", F(first), shown(d.reversal_spike_first_um, "um"));
  *g.out << fmt::format("  reversal spike {}          {}\n", F(second), shown(d.reversal_spike_second_um, "um"));
  *g.out << fmt::format("  straightness {}            {}\n", F(first), shown(d.straightness_first_um, "um"));
  *g.out << fmt::format("  straightness {}            {}\n", F(second), shown(d.straightness_second_um, "um"));
  if (d.cyclic_amplitude_um) {
    *g.out << fmt::format("  cyclic error              {:.3f} um, period {:.2f} mm, axis {}\n", *d.cyclic_amplitude_um,
                          *d.cyclic_period_mm, F(d.cyclic_axis == 0 ? first : second));
  } else {
    *g.out << "  cyclic error              not detected\n";
  }
  *g.out << fmt::format("\nradial deviation about the LSQ circles: RMS {:.3f} um; left by the signatures: {:.3f} um\n",
                        d.rms_before_um, d.rms_after_um);
  for (const auto& n : d.notes) *g.out << "note: " << n << "\n";
  return j;
}

}  // namespace

int importCircle(const Globals& g, const std::string& path, acquisition::CircleImportOptions options) {
  storage::Store store(g.db);
  options.software_version = kVersion;
  const storage::Id id = acquisition::importCircleCsv(store, path, options);
  const auto points = store.circlePoints(id).size();
  if (g.json) {
    *g.out << nlohmann::json{{"run_id", id}, {"points", points}}.dump() << "\n";
  } else {
    *g.out << fmt::format("imported run {}: {} circle points\n", id, points);
  }
  return 0;
}

int analyzeIso230_4(const Globals& g, storage::Id run_id) {
  storage::Store store(g.db);
  printIso230_4(g, store, run_id, loadCircle(store, run_id), true);
  return 0;
}

int analyzeBallbar(const Globals& g, storage::Id run_id) {
  storage::Store store(g.db);
  printDiagnosis(g, store, run_id, loadCircle(store, run_id), true);
  return 0;
}

int runBallbar(const Globals& g, const std::string& plan_path, const std::string& device_uri, const SimulationOptions& sim_options) {
  const auto plan = acquisition::CirclePlan::fromJson(nlohmann::json::parse(readTextFile(plan_path)), plan_path);
  if (drivers::DeviceUri::parse(device_uri).scheme != "mock") {
    throw InputError("circular tests drive the simulated machine (mock://ballbar); on a real machine run the part program "
                     "(`mtcal plan gcode PLAN`) with the bar's own software and import its data (`mtcal import circle`): "
                     "a triggered capture of circles is not built yet");
  }
  std::string file_json;
  const auto config = machineConfig(sim_options, &file_json);
  Simulation sim(config, demoInterferometer(), sim_options.time_scale);
  sim.setUpFor(plan);
  auto bar = sim.registry.openAs<drivers::ballbar::BallbarDevice>(device_uri);
  storage::Store store(g.db);
  const storage::Id machine_id = store.ensureMachine(machineName(config, !file_json.empty()), "simulated machine",
                                                     simulationDescription(config, file_json));
  const storage::Id campaign_id = store.addCampaign(machine_id, plan.name);
  acquisition::CircleRunOptions options;
  options.software_version = kVersion;
  options.stop_requested = g.stop;
  options.mount_bar = [&sim] { sim.world.ballbar->mountOnMachine(); };
  options.run_clock = &sim.run_clock;
  const auto result = acquisition::runCircleTest(store, campaign_id, *bar, sim.controller, plan, options);
  if (result.outcome == acquisition::RunOutcome::kInterrupted) {
    *g.err << fmt::format("run {} interrupted: {}; the completed directions are stored\n", result.run_id, result.reason);
    return 1;
  }
  if (!g.json) {
    *g.out << fmt::format("run {}: {} points, {} samples streamed, {} lost\n\n", result.run_id, result.points,
                          result.stats.samples, result.stats.lost_samples);
  }
  const StoredCircle stored = loadCircle(store, result.run_id);
  const auto iso = printIso230_4(g, store, result.run_id, stored, false);
  if (!g.json) *g.out << "\n";
  const auto diagnosis = printDiagnosis(g, store, result.run_id, stored, false);
  if (g.json) {
    *g.out << nlohmann::json{{"run_id", result.run_id},
                             {"points", result.points},
                             {"samples", result.stats.samples},
                             {"lost_samples", result.stats.lost_samples},
                             {"iso230_4", iso},
                             {"ballbar", diagnosis}}
                  .dump()
           << "\n";
  }
  return 0;
}

}  // namespace mtcal::app
