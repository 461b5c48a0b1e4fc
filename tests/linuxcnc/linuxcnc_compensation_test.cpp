// mtcal's LinuxCNC comp files checked on a real LinuxCNC 2.9 (Debian linuxcnc-uspace, headless,
// isolated by tests/linuxcnc/run-linuxcnc): the table is built by mtcal, written in both file
// types, loaded into LinuxCNC's joint 0, and the joint moved to the table's entries, between
// them and beyond them from both directions. At every stop the correction LinuxCNC applies
// (joint.0.backlash-corr, and motor-pos-cmd - pos-cmd) must be what mtcal says the table does,
// and what mtcal's virtual CNC applies on the same moves, within 0.1 um.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "mtcal/error.h"
#include "mtcal/mocks/virtual_machine.h"
#include "mtcal/processing/compensation_formats.h"

namespace mtcal {
namespace {

namespace fs = std::filesystem;
using processing::Direction;

constexpr double kToleranceUm = 0.1;  // the bound; measured differences are 1e-5 to 0.006 um

/// A machine's error on X: a pitch error of a few um with a reversal that grows along the axis.
processing::CompensationTable measuredTable() {
  processing::AxisError e;
  for (int i = 0; i <= 20; ++i) {
    const double x = 20.0 + 10.0 * i;  // 20 to 220 mm: the virtual CNC's travel starts at 0
    e.position.push_back(x);
    e.up_um.push_back(3.0 * std::sin(x / 40.0) + 0.01 * x);
    e.down_um.push_back(e.up_um.back() - 1.5 - 0.01 * x);
  }
  processing::TableOptions options;
  options.interval = 20.0;
  options.reference = 20.0;
  return processing::compensationTable(e, options);
}

/// Every entry and every mid-point going up and going down, beyond both ends, reversals in the
/// middle of the table and a move of no length (the correction stays as it was).
std::vector<double> moves() {
  std::vector<double> m;
  for (double x = 30.0; x <= 230.0; x += 10.0) m.push_back(x);
  m.push_back(235.0);
  for (double x = 215.0; x >= 10.0; x -= 10.0) m.push_back(x);
  for (double x : {15.0, 53.0, 47.0, 47.0, 160.0, 120.0, 140.0, 20.0}) m.push_back(x);
  return m;
}

struct LinuxCncRun {
  int exit_code = 0;
  nlohmann::json result;
  std::string log;
};

/// Runs LinuxCNC with `comp` as joint 0's COMP_FILE of `type`. Skips the test where LinuxCNC
/// cannot run (exit 77: not root, no namespaces, not installed), with the harness' reason.
LinuxCncRun runLinuxCnc(const std::string& comp, int type) {
  const fs::path dir = fs::temp_directory_path() / ("mtcal-lcnc-test-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / "table.comp") << comp;
  std::ofstream moves_file(dir / "moves");
  for (double x : moves()) moves_file << x << "\n";
  moves_file.close();
  const std::string command = std::string(MTCAL_LINUXCNC_HARNESS) + " --comp " + (dir / "table.comp").string() +
                              " --type " + std::to_string(type) + " --moves " + (dir / "moves").string() + " --out " +
                              (dir / "out.json").string() + " 2>" + (dir / "stderr").string();
  const int status = std::system(command.c_str());
  LinuxCncRun run;
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  std::stringstream log;
  log << std::ifstream(dir / "stderr").rdbuf();
  run.log = log.str();
  if (fs::exists(dir / "out.json")) run.result = nlohmann::json::parse(std::ifstream(dir / "out.json"));
  fs::remove_all(dir);
  return run;
}

class LinuxCncLoadsTheTable : public ::testing::TestWithParam<const char*> {};

TEST_P(LinuxCncLoadsTheTable, AndAppliesWhatMtcalSaysAtEveryStop) {
  const auto& format = processing::controllerFormat(GetParam());
  const int type = std::string(GetParam()) == "linuxcnc" ? 0 : 1;
  const auto file = format.write(measuredTable(), {"X", 0, ""});
  // What mtcal says the file does: the table read back as LinuxCNC reads it.
  const auto table = format.read(file.text, "X.comp");
  const auto run = runLinuxCnc(file.text, type);
  if (run.exit_code == 77) GTEST_SKIP() << "LinuxCNC cannot run here: " << run.log;
  ASSERT_EQ(run.exit_code, 0) << run.log;
  EXPECT_EQ(run.result.at("table").at("entries_loaded").get<std::size_t>(), table.position.size());
  EXPECT_TRUE(run.result.at("linuxcnc_table_messages").empty()) << run.result.at("linuxcnc_table_messages");

  // The virtual CNC on the same moves: the correction is what the table adds to its error.
  mocks::VirtualMachineConfig config;
  config.settle_time_constant_s = 0.0;
  mocks::WorldClock clock_bare(1000.0), clock_compensated(1000.0);
  mocks::VirtualMachine bare(config, clock_bare);
  config.compensation[0] = mocks::VirtualMachineConfig::AxisCompensation{table, format.rules};
  mocks::VirtualMachine compensated(config, clock_compensated);
  const auto virtualCorrectionUm = [&](double t_bare, double t_compensated) {
    return compensated.pointErrorUm({}, t_compensated + 1.0).x() - bare.pointErrorUm({}, t_bare + 1.0).x();
  };
  // Before any move neither applies a correction, whatever the table says at 0.
  const auto& home = run.result.at("home");
  EXPECT_NEAR((home.at("motor_pos_cmd_mm").get<double>() - home.at("pos_cmd_mm").get<double>()) * 1000.0, 0.0,
              kToleranceUm);
  EXPECT_NEAR(virtualCorrectionUm(0.0, 0.0), 0.0, kToleranceUm);

  const auto& stops = run.result.at("stops");
  ASSERT_EQ(stops.size(), moves().size());
  double worst_table_um = 0.0, worst_motor_um = 0.0, last_um = 0.0;
  for (const auto& s : stops) {
    const double x = s.at("target_mm").get<double>();
    const int direction = s.at("direction").get<int>();
    const double corr_um = s.at("backlash_corr_mm").get<double>() * 1000.0;
    const double motor_um = s.at("motor_minus_pos_cmd_mm").get<double>() * 1000.0;
    // Standing still keeps the last correction; otherwise the table of the direction moved in.
    const double expected_um =
        direction == 0 ? last_um
                       : table.correctionUm(x, direction > 0 ? Direction::kUp : Direction::kDown, format.rules);
    last_um = expected_um;
    EXPECT_NEAR(corr_um, expected_um, kToleranceUm) << "stop at " << x << " mm, direction " << direction;
    EXPECT_NEAR(motor_um, expected_um, kToleranceUm) << "stop at " << x << " mm, direction " << direction;
    const double t_bare = bare.moveTo(mocks::Axis::kX, x);
    const double t_compensated = compensated.moveTo(mocks::Axis::kX, x);
    EXPECT_NEAR(virtualCorrectionUm(t_bare, t_compensated), motor_um, kToleranceUm) << "virtual CNC at " << x << " mm";
    worst_table_um = std::max(worst_table_um, std::abs(corr_um - expected_um));
    worst_motor_um = std::max(worst_motor_um, std::abs(motor_um - expected_um));
  }
  std::cerr << GetParam() << ": " << stops.size() << " stops, largest difference from mtcal's table " << worst_table_um
            << " um (backlash-corr), " << worst_motor_um << " um (motor-pos-cmd - pos-cmd)\n";
}

INSTANTIATE_TEST_SUITE_P(BothFileTypes, LinuxCncLoadsTheTable, ::testing::Values("linuxcnc", "linuxcnc-trim"),
                         [](const auto& info) { return std::string(info.param) == "linuxcnc" ? "Type0" : "Type1"; });

TEST(LinuxCncComment, AHeaderLineLoadsNothingWithoutAWordSoMtcalRefusesIt) {
  const auto& format = processing::controllerFormat("linuxcnc-trim");
  const std::string file = "# nominal forward reverse\n" + format.write(measuredTable(), {"X", 0, ""}).text;
  EXPECT_THROW(format.read(file, "X.comp"), InputError);
  const auto run = runLinuxCnc(file, 1);
  if (run.exit_code == 77) GTEST_SKIP() << "LinuxCNC cannot run here: " << run.log;
  ASSERT_FALSE(run.result.is_null()) << run.log;
  EXPECT_TRUE(run.result.at("linuxcnc_table_messages").empty());  // LinuxCNC says nothing...
  for (const auto& s : run.result.at("stops"))                    // ...and corrects nothing
    EXPECT_EQ(s.at("backlash_corr_mm").get<double>(), 0.0) << s.at("target_mm");
}

}  // namespace
}  // namespace mtcal
