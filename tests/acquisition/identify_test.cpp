#include <fmt/format.h>
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "../support/rigid_residual.h"
#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/acquisition/error_models.h"
#include "mtcal/acquisition/import_linear.h"
#include "mtcal/acquisition/linear_run.h"
#include "mtcal/error.h"
#include "mtcal/services/export.h"
#include "mtcal/services/workshop.h"

// Round trips on the virtual machine: known error functions -> simulated measurement plans
// run through the whole acquisition path (mock interferometer over the real driver, SQLite)
// -> identification through the model -> compared with the truth.
//
// Noise-limited tolerance: the emulated interferometer reads with 0.02 um / 0.05 urad noise
// per sample, 200 samples per capture (0.0014 um / 0.0035 urad), two cycles per node; the
// positioning scatter and the environment sensors' noise are off, the 2.5 um backlash is
// common to every approach of these unidirectional runs. The simulated world runs in lock
// step with the runs, so a seed gives the same campaign on any machine under any load: the
// figures are asserted at the values documented in docs/multibody-model.md, node values
// within 0.03 um / urad of the truth (up to 0.024 seen: angles come from differences of
// straightness runs at lever arms of 100-200 mm, which multiply the readings' noise and
// second-order terms) and E within 0.0094 and 0.0049 um, plus 5 % for another compiler's
// rounding.
namespace mtcal::acquisition {
namespace {

processing::MultibodyModel patentMachine() {
  std::ifstream in(std::string(MTCAL_EXAMPLES_DIR) + "/machines/vmc3-cn104200063.model.json");
  return processing::MultibodyModel::fromJson(nlohmann::json::parse(in), "vmc3");
}

/// Polynomial in metres of travel (um/m^k or urad/m^k), as mocks::ErrorCurve.
mocks::ErrorCurve poly(std::vector<double> c) { return mocks::ErrorCurve{std::move(c), {}}; }

/// sign * the integral of a polynomial in metres: a straightness whose slope (um/mm) is
/// 1e-3 x the rotation (urad), i.e. d/dp in um/m equals the rotation in urad.
mocks::ErrorCurve integral(const mocks::ErrorCurve& rotation, double sign) {
  std::vector<double> c{0.0};
  for (std::size_t k = 0; k < rotation.poly.size(); ++k)
    c.push_back(sign * rotation.poly[k] / static_cast<double>(k + 1));
  return poly(c);
}

mocks::VirtualMachineConfig quietMachine() {
  auto m = mocks::VirtualMachineConfig::demo(11);
  m.errors.clear();
  for (auto& a : m.axes) a.positioning_sigma_um = 0.0;
  return m;
}

/// The demo interferometer with noise-free environment sensors: a 0.005 K material sensor
/// noise alone moves a 400 mm reading by 0.023 um through the expansion correction.
mocks::InterferometerEmulatorConfig quietInterferometer() {
  auto c = services::demoInterferometer();
  c.env_noise_temp_k = 0.0;
  c.env_noise_pressure_pa = 0.0;
  c.env_noise_humidity_pct = 0.0;
  return c;
}

struct Bench {
  explicit Bench(const mocks::VirtualMachineConfig& machine)
      : sim(machine, quietInterferometer(), mtcal::testing::timeScale(400.0)),
        store(dir.file("id.sqlite")),
        device(sim.registry.openAs<drivers::interferometer::InterferometerDevice>("mock://interferometer")),
        campaign(store.addCampaign(store.ensureMachine("vm", "", "{}"), "identification")) {}

  /// A unidirectional run of `axis` over 50..450 mm (nodes every 50 mm), two cycles.
  storage::Id run(const std::string& axis, const std::string& measures, std::map<std::string, double> line,
                  std::array<double, 3> reflector) {
    LinearPlan plan;
    plan.axis = axis;
    plan.measures = measures;
    plan.start_mm = 50;
    plan.end_mm = 450;
    plan.step_mm = 50;
    plan.repeats = 2;
    plan.bidirectional = false;
    plan.line_position_mm = std::move(line);
    plan.reflector_offset_mm = reflector;
    sim.setUpFor(plan);
    LinearRunOptions options;
    options.run_clock = &sim.run_clock;  // the simulated world runs in lock step with the run
    LinearRun run(store, *device, &sim.controller, options);
    return run.start(plan, campaign, std::nullopt);
  }

  mtcal::testing::TempDir dir;
  services::Simulation sim;
  storage::Store store;
  std::shared_ptr<drivers::interferometer::InterferometerDevice> device;
  storage::Id campaign;
};

Eigen::VectorXd trueErrors(const processing::MultibodyModel& m, const mocks::VirtualMachineConfig& c,
                           const Eigen::VectorXd& q) {
  Eigen::VectorXd e(static_cast<Eigen::Index>(m.terms().size()));
  for (std::size_t i = 0; i < m.terms().size(); ++i) {
    const auto& term = m.terms()[i];
    e(static_cast<Eigen::Index>(i)) = c.trueError(term.name, term.motion ? q(m.coordinateOfJoint(term.joint)) : 0.0);
  }
  return e;
}

processing::ErrorModel fitted(const processing::MultibodyModel& m, const processing::LineIdentification& id) {
  std::vector<processing::ErrorFunction> functions;
  for (const auto& c : id.curves) functions.push_back(processing::ErrorFunction::fit(c, {}));
  return processing::ErrorModel(m, std::move(functions));
}

/// Largest |E_identified - E_true| over a grid in the measured volume, after removing the best
/// rigid-body motion of the workpiece frame (the gauge no line measurement fixes) and, with
/// `free_squareness`, the three shears of the squareness errors.
double gaugeFreeResidualUm(const processing::MultibodyModel& m, const mocks::VirtualMachineConfig& truth,
                           const processing::ErrorModel& identified, bool free_squareness = false) {
  std::vector<Eigen::Vector3d> points, diffs;
  for (double x = 60; x <= 440; x += 95)
    for (double y = 60; y <= 440; y += 95)
      for (double z = 60; z <= 440; z += 95) {
        const Eigen::Vector3d q(x, y, z);
        points.push_back(m.idealPoint(q));
        diffs.push_back(identified.predictUm(q) - m.spatialErrorUm(q, trueErrors(m, truth, q)));
      }
  return mtcal::testing::residualAfterRigidMotionUm(points, diffs, free_squareness);
}

void expectRelativeTruth(const processing::LineIdentification& id, const mocks::VirtualMachineConfig& truth,
                         const std::vector<std::string>& names, double tolerance) {
  for (const auto& name : names) {
    const auto it = std::find_if(id.curves.begin(), id.curves.end(), [&](const auto& c) { return c.name == name; });
    ASSERT_NE(it, id.curves.end()) << name;
    for (std::size_t n = 0; n < it->position_mm.size(); ++n) {
      const double x = it->position_mm[n];
      EXPECT_NEAR(it->mean[n], truth.trueError(name, x) - truth.trueError(name, 50.0), tolerance)
          << name << " at " << x;
    }
  }
}

/// The campaign's runs written out as another program would (services::exportCampaign: one
/// CSV per run and the manifest of axis, error, line and reflector), imported back as a new
/// campaign and identified: the same curves as from the acquired runs, node by node within
/// 0.01 um / urad (the export writes every value so that it reads back to the same double, so
/// anything above 0 means a setup lost on the way).
void expectTheSameModelAfterExportAndImport(Bench& bench, const processing::MultibodyModel& m,
                                            const processing::LineIdentificationOptions& options,
                                            const std::vector<storage::Id>& runs,
                                            const processing::LineIdentification& acquired) {
  services::SessionOptions session_options;
  session_options.db_path = bench.dir.file("id.sqlite");
  services::Session session(session_options);
  const auto exported = services::exportCampaign(session, bench.campaign, bench.dir.file("exported"));
  const auto imported = importLinearCampaign(bench.store, exported.manifest, {});
  ASSERT_EQ(imported.run_ids.size(), runs.size());
  const auto again = processing::identifyFromLines(m, linesFromRuns(bench.store, imported.run_ids, m), options);
  ASSERT_EQ(again.curves.size(), acquired.curves.size());
  double largest = 0.0;
  for (std::size_t c = 0; c < acquired.curves.size(); ++c) {
    ASSERT_EQ(again.curves[c].name, acquired.curves[c].name);
    ASSERT_EQ(again.curves[c].mean.size(), acquired.curves[c].mean.size()) << acquired.curves[c].name;
    for (std::size_t n = 0; n < acquired.curves[c].mean.size(); ++n) {
      EXPECT_NEAR(again.curves[c].mean[n], acquired.curves[c].mean[n], 0.01) << acquired.curves[c].name << " " << n;
      largest = std::max(largest, std::abs(again.curves[c].mean[n] - acquired.curves[c].mean[n]));
    }
  }
  std::cout << "exported and imported as a campaign: largest node difference " << largest << " um or urad\n";
}

// Direct method, all 21 errors: positioning, straightness and angular runs of each axis, a
// second straightness run at another lever arm for each roll, straightness pairs for the
// squareness errors. The truth is smooth at the 50 mm node spacing (a 180 mm wave would
// leave ~0.2 um between nodes: sampling, not identification).
TEST(Identification, DirectMethodRecoversThe21ErrorsOfTheVirtualMachine) {
  auto truth = quietMachine();
  truth.errors["EXX"] = poly({0.0, 9.0, -7.0});
  truth.errors["EYX"] = poly({0.0, -2.0, 6.0});
  truth.errors["EZX"] = poly({0.0, 3.0, -4.0});
  truth.errors["EAX"] = poly({0.0, 14.0});
  truth.errors["EBX"] = poly({0.0, 18.0, -8.0});
  truth.errors["ECX"] = poly({1.0, -10.0, 14.0});
  truth.errors["EXY"] = poly({0.0, 4.0, -5.0});
  truth.errors["EYY"] = poly({0.0, -6.0, 4.0});
  truth.errors["EZY"] = poly({0.0, 2.0, 3.0});
  truth.errors["EAY"] = poly({0.0, 9.0, -6.0});
  truth.errors["EBY"] = poly({0.0, -12.0});
  truth.errors["ECY"] = poly({2.0, 5.0});
  truth.errors["EXZ"] = poly({0.0, 1.0, 4.0});
  truth.errors["EYZ"] = poly({0.0, -3.0, 2.0});
  truth.errors["EZZ"] = poly({0.0, 5.0, 3.0});
  truth.errors["EAZ"] = poly({0.0, 7.0});
  truth.errors["EBZ"] = poly({0.0, -8.0, 5.0});
  truth.errors["ECZ"] = poly({0.0, 10.0});
  truth.errors["EC0Y"] = poly({12.0});
  truth.errors["EB0Z"] = poly({-8.0});
  truth.errors["EA0Z"] = poly({5.0});
  Bench bench(truth);
  const std::map<std::string, double> home{{"X", 200}, {"Y", 150}, {"Z", 100}};
  auto at = [&](const std::string& axis) {
    auto line = home;
    line.erase(axis);
    return line;
  };
  const std::array<double, 3> off{0, 25, 45};
  std::vector<storage::Id> runs;
  for (const auto& [axis, measures, reflector] :
       std::vector<std::tuple<std::string, std::string, std::array<double, 3>>>{
           {"X", "EXX", off},
           {"X", "EYX", off},
           {"X", "EZX", off},
           {"X", "EBX", off},
           {"X", "ECX", off},
           {"Y", "EYY", off},
           {"Y", "EXY", off},
           {"Y", "EZY", off},
           {"Y", "EAY", off},
           {"Y", "ECY", off},
           {"Z", "EZZ", off},
           {"Z", "EXZ", off},
           {"Z", "EYZ", off},
           {"Z", "EAZ", off},
           {"Z", "EBZ", off},
           // Rolls: the same straightness at a second lever arm.
           {"X", "EZX", {0, 225, 45}},
           {"Y", "EZY", {150, 25, 45}},
           {"Z", "EXZ", {0, 125, 45}}}) {
    runs.push_back(bench.run(axis, measures, at(axis), reflector));
  }
  const auto m = patentMachine();
  const auto id = processing::identifyFromLines(m, linesFromRuns(bench.store, runs, m), {});
  EXPECT_EQ(id.curves.size(), 21u);
  for (const auto& note : id.notes) ADD_FAILURE() << "unexpected note: " << note;
  expectRelativeTruth(id, truth, {"EXX", "EYY", "EZZ", "EAX", "EBX", "ECX", "EAY", "EBY", "ECY", "EAZ", "EBZ", "ECZ"},
                      0.03);
  const double residual = gaugeFreeResidualUm(m, truth, fitted(m, id));
  EXPECT_LT(residual, 0.0094 * 1.05);
  std::cout << "direct identification, 18 runs: largest gauge-free |E - E_true| = " << residual << " um\n";
  expectTheSameModelAfterExportAndImport(bench, m, {}, runs, id);
}

// 9-line method: three positioning runs per axis at non-collinear lever arms, set by the
// other axes' positions (X, Y) or by the reflector (Z: nothing sits above it). The truth
// obeys the rigid-body assumption the method needs; rolls and squareness are zero (the
// method cannot see them and says so).
TEST(Identification, NineLineMethodRecoversTheVirtualMachine) {
  auto truth = quietMachine();
  truth.errors["EXX"] = poly({0.0, 9.0, -7.0});
  truth.errors["EBX"] = poly({12.0, -40.0});
  truth.errors["ECX"] = poly({-5.0, 30.0});
  truth.errors["EYY"] = poly({0.0, -4.0});
  truth.errors["EAY"] = poly({6.0, -10.0});
  truth.errors["ECY"] = poly({0.0, 20.0});
  truth.errors["EZZ"] = poly({0.0, 5.0});
  truth.errors["EAZ"] = poly({-3.0, 20.0});
  truth.errors["EBZ"] = poly({0.0, 15.0});
  truth.errors["EYX"] = integral(truth.errors["ECX"], +1);
  truth.errors["EZX"] = integral(truth.errors["EBX"], -1);
  truth.errors["EXY"] = integral(truth.errors["ECY"], -1);
  truth.errors["EZY"] = integral(truth.errors["EAY"], +1);
  truth.errors["EXZ"] = integral(truth.errors["EBZ"], +1);
  truth.errors["EYZ"] = integral(truth.errors["EAZ"], -1);
  Bench bench(truth);
  std::vector<storage::Id> runs;
  const std::array<double, 3> none{0, 0, 0};
  // X: lever arms through the Y and Z positions.
  runs.push_back(bench.run("X", "EXX", {{"Y", 100}, {"Z", 100}}, none));
  runs.push_back(bench.run("X", "EXX", {{"Y", 300}, {"Z", 100}}, none));
  runs.push_back(bench.run("X", "EXX", {{"Y", 100}, {"Z", 300}}, none));
  // Y: Z position and the reflector's X offset.
  runs.push_back(bench.run("Y", "EYY", {{"X", 200}, {"Z", 100}}, none));
  runs.push_back(bench.run("Y", "EYY", {{"X", 200}, {"Z", 300}}, none));
  runs.push_back(bench.run("Y", "EYY", {{"X", 200}, {"Z", 100}}, {150, 0, 0}));
  // Z: the reflector only.
  runs.push_back(bench.run("Z", "EZZ", {{"X", 200}, {"Y", 150}}, none));
  runs.push_back(bench.run("Z", "EZZ", {{"X", 200}, {"Y", 150}}, {150, 0, 0}));
  runs.push_back(bench.run("Z", "EZZ", {{"X", 200}, {"Y", 150}}, {0, 150, 0}));
  const auto m = patentMachine();
  processing::LineIdentificationOptions options;
  options.method = processing::IdentificationMethod::kNineLine;
  const auto id = processing::identifyFromLines(m, linesFromRuns(bench.store, runs, m), options);
  EXPECT_EQ(id.curves.size(), 15u);
  expectRelativeTruth(id, truth, {"EXX", "EBX", "ECX", "EYY", "EAY", "ECY", "EZZ", "EAZ", "EBZ"}, 0.03);
  for (const auto& a : id.axes) EXPECT_LT(a.condition_number, 100.0) << a.coordinate;
  // Squareness is out of the method's reach (and the rotations' values at the first node,
  // which act like it): compared up to the gauge and the three squareness shears.
  const double residual = gaugeFreeResidualUm(m, truth, fitted(m, id), true);
  EXPECT_LT(residual, 0.0049 * 1.05);
  std::cout << "9-line identification, 9 runs: largest gauge-free |E - E_true| = " << residual << " um\n";
  expectTheSameModelAfterExportAndImport(bench, m, options, runs, id);

  // The same runs without the third lever arm of X: refused with the condition number.
  std::vector<storage::Id> collinear = runs;
  collinear[2] = bench.run("X", "EXX", {{"Y", 500}, {"Z", 100}}, none);  // on the line of the first two
  try {
    processing::identifyFromLines(m, linesFromRuns(bench.store, collinear, m), options);
    FAIL() << "collinear lever arms were accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("condition number"), std::string::npos) << e.what();
    // Each line named where it stands: the other axes and the optics.
    EXPECT_NE(std::string(e.what()).find(fmt::format("run {} at y 300, z 100, optics at (0.0, 0.0, ", runs[1])),
              std::string::npos)
        << e.what();
  }
}

// An imported run (no plan keys) is a positioning line at the tool point with the other axes
// at 0; a run that is not linear is refused by name.
TEST(Identification, RunsWithoutASetUpAreLinesAtTheToolPoint) {
  auto truth = quietMachine();
  truth.errors["EXX"] = poly({0.0, 9.0});
  Bench bench(truth);
  const auto run = bench.run("X", "", {}, {0, 0, 0});
  const auto lines = linesFromRuns(bench.store, {run}, patentMachine());
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0].measures, "EXX");
  EXPECT_EQ(lines[0].component, 0);
  EXPECT_EQ(lines[0].q, Eigen::Vector3d::Zero());
  EXPECT_TRUE(lines[0].point_mm.isApprox(Eigen::Vector3d(0, 0, 0)));
  EXPECT_EQ(lines[0].position_mm.size(), 9u);
  EXPECT_NEAR(lines[0].mean.back() - lines[0].mean.front(), 9.0 * 0.4, 0.01);  // 9 um/m over 400 mm
  EXPECT_THROW(linesFromRuns(bench.store, {run + 100}, patentMachine()), Error);
}

}  // namespace
}  // namespace mtcal::acquisition
