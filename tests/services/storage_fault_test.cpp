// The disk fills up, or fails, in the middle of a run (SQLITE_FULL or SQLITE_IOERR through a
// VFS over the platform's, tests/support/full_disk_vfs.h): the error says so, nothing committed is lost, the archive
// stays sound, and the run resumes once there is space again.

#include <gtest/gtest.h>

#include <string>

#include "../support/full_disk_vfs.h"
#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/error.h"
#include "mtcal/services/resume.h"
#include "service_support.h"

namespace mtcal::services {
namespace {

/// Fills the disk once `after` targets are stored.
struct FillDiskAfter final : Observer {
  FillDiskAfter(mtcal::testing::FullDiskVfs& disk, std::size_t after) : disk_(disk), after_(after) {}
  void onProgress(const Progress& p) override {
    if (p.done == after_) disk_.setFree(0);
  }

 private:
  mtcal::testing::FullDiskVfs& disk_;
  std::size_t after_;
};

struct StorageFault {
  const char* name;
  int sqlite_code;
  const char* message;  ///< what the error says
};

class StorageFaults : public ::testing::TestWithParam<StorageFault> {};

TEST_P(StorageFaults, MidRunLosesNothingCommittedAndTheRunResumes) {
  mtcal::testing::FullDiskVfs disk;
  disk.setFailure(GetParam().sqlite_code);
  const mtcal::testing::TempDir dir;
  const std::string db = dir.file("full.sqlite");
  FillDiskAfter fill(disk, 3);
  LinearRunRequest request;
  request.plans = {mtcal::testing::smallLinearPlan()};
  request.simulation.time_scale = mtcal::testing::timeScale(400.0);
  std::vector<storage::TargetRecord> kept;
  {
    Session session({db, "", &fill, nullptr, nullptr});
    try {
      runLinear(session, request);
      FAIL() << "the run went on with a full disk";
    } catch (const StorageError& e) {
      EXPECT_NE(std::string(e.what()).find(GetParam().message + ("store '" + db + "'")), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("committed before is kept"), std::string::npos) << e.what();
    }
    EXPECT_GE(disk.refused(), 1);
    disk.setUnlimited();
    kept = session.store().targets(1);
  }
  EXPECT_EQ(kept.size(), 3u);  // the three committed targets, nothing of the fourth
  {
    storage::Store store(db);
    storage::Statement check(store.database(), "PRAGMA integrity_check");
    ASSERT_TRUE(check.step());
    EXPECT_EQ(check.getText(0), "ok");
    // Its end could not be stored, but this process no longer records it: it reads interrupted.
    EXPECT_EQ(store.run(1).status, storage::run_status::kInterrupted);
    EXPECT_TRUE(store.run(1).stale);
  }
  // Space again: the run resumes where it stopped and keeps what it had.
  Session again(mtcal::testing::onArchive(db));
  SimulationOptions simulation;
  simulation.time_scale = request.simulation.time_scale;
  const auto resumed = std::get<LinearRunResult>(resumeRun(again, 1, simulation));
  EXPECT_EQ(resumed.status, "completed");
  EXPECT_EQ(resumed.targets, 12);
  const auto all = again.store().targets(1);
  for (std::size_t k = 0; k < kept.size(); ++k) {
    EXPECT_EQ(all[k].seq, kept[k].seq);
    EXPECT_EQ(all[k].deviation_um, kept[k].deviation_um);
  }
}

INSTANTIATE_TEST_SUITE_P(Storage, StorageFaults,
                         ::testing::Values(StorageFault{"DiskFull", SQLITE_FULL, "the disk holding "},
                                           StorageFault{"IoError", SQLITE_IOERR_WRITE, "I/O error on "}),
                         [](const auto& info) { return std::string(info.param.name); });

}  // namespace
}  // namespace mtcal::services
