// The loop closed on the simulated machine: an axis measured, its table written for a
// controller, the virtual CNC running that table, the axis measured again and the table
// iterated from the run that ran it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/services/archive.h"
#include "mtcal/services/compensate.h"
#include "mtcal/services/linear.h"
#include "service_support.h"

namespace mtcal::services {
namespace {

/// The demo machine's X axis: the 20 mm grid of ISO 230-2, or random offsets from it (a
/// verification that does not measure at the table's own entries).
LinearRunRequest demoAxis(const std::string& plan = "x_axis_iso230-2.json") {
  LinearRunRequest r;
  r.plan_path = MTCAL_EXAMPLES_DIR "/plans/" + plan;
  r.plans = {acquisition::LinearPlan::fromJson(nlohmann::json::parse(readTextFile(r.plan_path)), r.plan_path)};
  r.simulation.seed = 1;
  r.simulation.time_scale = mtcal::testing::timeScale(400.0);
  return r;
}

TEST(CompensateService, TheVirtualCncRunsTheTableAndTheIterationConverges) {
  const mtcal::testing::TempDir dir;
  Session session(mtcal::testing::onArchive(dir.file("c.sqlite")));
  const auto before = runLinear(session, demoAxis()).runs.front();
  ASSERT_EQ(before.status, "completed");
  CompensateRequest request;
  request.controller = "linuxcnc";
  const auto first = compensateRun(session, before.run_id, request);
  EXPECT_TRUE(first.existing_path.empty());
  const std::string table = dir.file("X.comp");
  writeTextFile(table, first.file.text);

  auto compensated = demoAxis("x_axis_random_offsets.json");
  compensated.simulation.compensation = {{"", table, "linuxcnc"}};
  const auto after = runLinear(session, compensated).runs.front();
  ASSERT_EQ(after.status, "completed");
  // The run keeps the table its controller ran.
  const auto ran = appliedTables(session.store().run(after.run_id).compensation_json);
  ASSERT_TRUE(ran[0].has_value());
  EXPECT_EQ(ran[0]->file, table);
  EXPECT_EQ(ran[0]->table.position, first.table.position);
  EXPECT_EQ(showRun(session, after.run_id).document()["compensation"]["X"]["controller"], "linuxcnc");
  // The virtual CNC applies what the truth says it does: the measured means agree with the
  // compensated machine's static error as they do on the bare machine.
  ASSERT_TRUE(after.simulation_check.has_value());
  EXPECT_LT(after.simulation_check->max_abs_um, 1.0);
  const auto& e_before = *before.iso230_2->result.E_um;
  const auto& e_after = *after.iso230_2->result.E_um;
  const auto& m_before = *before.iso230_2->result.M_um;
  const auto& m_after = *after.iso230_2->result.M_um;
  std::printf("compensated on the demo machine: E %.3f -> %.3f um, M %.3f -> %.3f um, R %.3f -> %.3f um\n", e_before,
              e_after, m_before, m_after, *before.iso230_2->result.R_um, *after.iso230_2->result.R_um);
  EXPECT_LT(e_after, e_before / 2.0);
  EXPECT_LT(m_after, m_before / 2.0);

  // The second iteration starts from the table the run ran (no --existing needed) and
  // changes it by what was left: at most the repeatability's level.
  const auto second = compensateRun(session, after.run_id, request);
  EXPECT_EQ(second.existing_path, table);
  double largest_change_um = 0.0;
  for (std::size_t i = 0; i < second.table.position.size(); ++i) {
    largest_change_um = std::max({largest_change_um, std::abs(second.table.up_um[i] - first.table.up_um[i]),
                                  std::abs(second.table.down_um[i] - first.table.down_um[i])});
  }
  std::printf("second iteration: the table changes by at most %.3f um\n", largest_change_um);
  EXPECT_LT(largest_change_um, *after.iso230_2->result.R_um);
}

}  // namespace
}  // namespace mtcal::services
