#include "mtcal/acquisition/stream_recorder.h"

#include <gtest/gtest.h>

#include "../support/temp_dir.h"
#include "mtcal/error.h"
#include "mtcal/services/workshop.h"

namespace mtcal::acquisition {
namespace {

namespace ifm = drivers::interferometer;

class StreamRecorderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto emulator = services::demoInterferometer();
    emulator.paced = false;  // as fast as the pipeline takes it
    sim_ = std::make_unique<services::Simulation>(mocks::VirtualMachineConfig::demo(1), emulator, 1.0);
  }
  storage::Id newRun(storage::Store& store) {
    storage::NewRun r;
    r.campaign_id = store.addCampaign(store.ensureMachine("vm", "", "{}"), "c");
    r.kind = "stream";
    r.name = "stream";
    return store.addRun(r);
  }
  mtcal::testing::TempDir dir_;
  std::string db_ = dir_.file("stream.sqlite");
  std::unique_ptr<services::Simulation> sim_;
};

TEST_F(StreamRecorderTest, StoresA50kHzStreamWithoutLoss) {
  storage::Store store(db_);
  const auto run = newRun(store);
  auto device = sim_->registry.openAs<ifm::InterferometerDevice>("mock://interferometer");
  StreamRecordOptions options;
  options.rate_hz = 50000;
  options.sample_limit = 200000;
  options.overflow = OverflowPolicy::kBlock;
  const auto result = recordStream(*device, store, run, options);
  EXPECT_EQ(result.stored, 200000u);
  EXPECT_EQ(result.dropped, 0u);
  EXPECT_EQ(result.stream.lost_samples, 0u);
  EXPECT_GE(result.commits, 1u);
  EXPECT_EQ(store.sampleCount(run), 200000);
  storage::Statement st(store.database(),
                        "SELECT MIN(device_seq), MAX(device_seq), COUNT(DISTINCT device_seq) FROM samples");
  ASSERT_TRUE(st.step());
  EXPECT_EQ(st.getInt(0), 0);
  EXPECT_EQ(st.getInt(1), 199999);
  EXPECT_EQ(st.getInt(2), 200000);
}

TEST_F(StreamRecorderTest, AFailureKeepsWhatWasCommitted) {
  storage::Store store(db_);
  const auto run = newRun(store);
  auto device = sim_->registry.openAs<ifm::InterferometerDevice>("mock://interferometer");
  StreamRecordOptions options;
  options.rate_hz = 50000;
  options.duration = std::chrono::milliseconds(60000);  // a bound: the unplug ends it long before
  options.commit_interval = std::chrono::milliseconds(10);
  // Unplugged after the first 30 000 samples (0.6 s of the stream): every one of them
  // reached the host before the failure, and is stored.
  sim_->world.interferometer->updateFaults([](auto& f) { f.disconnect_at_seq = 30000; });
  EXPECT_THROW(recordStream(*device, store, run, options), TransportError);
  EXPECT_EQ(store.sampleCount(run), 30000);
  storage::Statement st(store.database(), "SELECT MIN(device_seq), MAX(device_seq) FROM samples");
  ASSERT_TRUE(st.step());
  EXPECT_EQ(st.getInt(0), 0);
  EXPECT_EQ(st.getInt(1), 29999);
}

}  // namespace
}  // namespace mtcal::acquisition
