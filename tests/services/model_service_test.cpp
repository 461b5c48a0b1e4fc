#include <gtest/gtest.h>

#include <fstream>
#include <numbers>

#include "../support/temp_dir.h"
#include "mtcal/error.h"
#include "mtcal/services/compensate.h"
#include "mtcal/services/grind.h"
#include "mtcal/services/model.h"

// Error models and the grinder's operations through services, on hand-computed models.
namespace mtcal::services {
namespace {

const std::string kMachine = MTCAL_EXAMPLES_DIR "/machines/vmc3-cn104200063.model.json";

std::string write(const mtcal::testing::TempDir& dir, const std::string& name, const std::string& text) {
  const auto path = dir.file(name);
  std::ofstream(path) << text;
  return path;
}

// EXX = 0.01 um/mm x (exact, 3 repeats per node) and EC0Y = 10 urad. At (300, 200, 250) the
// tool point moves by EXX(300) = 3 um and by EC0Y x r = -10e-6 * 200 mm = -2 um in x:
// E_x = P_ideal - P = -(3 - 2) = -1 um.
TEST(ModelService, ImportsPredictsAndTabulatesAHandComputedModel) {
  const mtcal::testing::TempDir dir;
  Session session({dir.file("m.sqlite"), "", nullptr, nullptr, nullptr});
  std::string csv = "error,position_mm,value\n";
  for (int p = 50; p <= 600; p += 50) {
    for (int r = 0; r < 3; ++r) csv += "EXX," + std::to_string(p) + "," + std::to_string(0.01 * p) + "\n";
  }
  csv += "EC0Y,,10\n";
  ModelFitRequest request;
  request.csv_path = write(dir, "c.csv", csv);
  request.machine_path = kMachine;
  const auto stored = importModel(session, request);
  EXPECT_EQ(stored.document()["schema_version"], 1);
  EXPECT_NE(std::find(stored.errors.begin(), stored.errors.end(), "EXX"), stored.errors.end());
  const auto listed = listModels(session);
  ASSERT_EQ(listed.size(), 1u);
  EXPECT_EQ(listed.front().name, "c.csv");  // named after its file, not the folder it was in

  const auto at = predictModel(session, stored.model_id, "", write(dir, "p.csv", "x_mm,y_mm,z_mm\n300,200,250\n"));
  ASSERT_EQ(at.points.size(), 1u);
  EXPECT_NEAR(at.error_um.front().x(), -1.0, 1e-6);
  const auto grid = predictModel(session, stored.model_id, "50:600:3,0:100:2,200:200:1", "");
  EXPECT_EQ(grid.points.size(), 6u);
  EXPECT_EQ(grid.csv().substr(0, grid.csv().find('\n')), "x_mm,y_mm,z_mm,ex_um,ey_um,ez_um,sx_um,sy_um,sz_um");
  EXPECT_THROW(predictModel(session, stored.model_id, "50:600:3", ""), InputError);  // one axis of three

  // The X table at y = 0: the reading is EXX alone, 0.01 um/mm, the same both ways (no
  // extensions), the correction its negative.
  ModelAxisRequest axis;
  axis.from_mm = 100.0;
  axis.to_mm = 500.0;
  axis.step_mm = 100.0;
  axis.at = "300,0,250";
  const auto e = modelAxisError(session, stored.model_id, axis);
  ASSERT_EQ(e.error.position.size(), 5u);
  for (std::size_t i = 0; i < 5; ++i) {
    EXPECT_NEAR(std::abs(e.error.up_um[i]), 0.01 * e.error.position[i], 1e-6) << e.error.position[i];
    EXPECT_DOUBLE_EQ(e.error.up_um[i], e.error.down_um[i]);
  }
  EXPECT_TRUE(e.applied.empty());
  // The LinuxCNC table of it: the correction is the error's negative, the same both ways.
  CompensateRequest table;
  table.controller = "linuxcnc-trim";
  table.axis = "x";
  table.table.start = 100.0;
  table.table.end = 500.0;
  table.table.interval = 100.0;
  table.at = "300,0,250";
  const auto c = compensateModel(session, stored.model_id, table);
  ASSERT_EQ(c.table.position, e.error.position);
  for (std::size_t i = 0; i < 5; ++i)
    EXPECT_NEAR(c.table.up_um[i], -e.error.up_um[i], 5e-5);  // as the comp file holds it (1e-6 mm)
  EXPECT_FALSE(c.table.bidirectional());
  EXPECT_EQ(c.axis, "X");
  EXPECT_NE(c.file.setup.find("[JOINT_0]"), std::string::npos);
  EXPECT_EQ(c.document()["rows"].size(), 5u);
  axis.axis = "C";
  EXPECT_THROW(modelAxisError(session, stored.model_id, axis), InputError);
}

// The example C-axis test: length changes made through the grinder model from known errors.
TEST(GrindService, IdentifiesTheCAxisOfTheExample) {
  const std::string examples = MTCAL_EXAMPLES_DIR;
  const auto r =
      grindIdentify(examples + "/grinding/c-axis-readings.csv", examples + "/machines/grinder-xc-mks8332a.model.json",
                    examples + "/grinding/c-axis-layout.json");
  EXPECT_EQ(r.result.not_determined, std::vector<std::string>{"ECC"});
  ASSERT_EQ(r.result.coordinate.size(), 24u);
  EXPECT_EQ(r.result.coordinate[4], 60.0);
  const double c = 60.0 * std::numbers::pi / 180.0;
  const auto term = [&](const std::string& name) {
    const auto it = std::find(r.result.terms.begin(), r.result.terms.end(), name);
    return r.result.values(4, it - r.result.terms.begin());
  };
  EXPECT_NEAR(term("EXC"), 3.0 * std::sin(c), 1e-4);  // the file's 6 decimals of um
  EXPECT_NEAR(term("EAC"), 5.0 * std::sin(c), 1e-4);
  EXPECT_EQ(r.document()["values"].size(), 24u);
}

}  // namespace
}  // namespace mtcal::services
