#include "mtcal/acquisition/sample_queue.h"

#include <gtest/gtest.h>

#include <cmath>
#include <thread>

#include "mtcal/acquisition/capture.h"

namespace mtcal::acquisition {
namespace {

using namespace std::chrono_literals;

std::vector<drivers::Sample> run(std::uint32_t first, std::size_t n) {
  std::vector<drivers::Sample> v(n);
  for (std::size_t i = 0; i < n; ++i) v[i].seq = first + static_cast<std::uint32_t>(i);
  return v;
}

TEST(SampleQueue, DropNewestCountsWhatDidNotFit) {
  SampleQueue q(10, OverflowPolicy::kDropNewest);
  q.push(run(0, 7));
  q.push(run(7, 7));
  EXPECT_EQ(q.size(), 10u);
  EXPECT_EQ(q.dropped(), 4u);
  std::vector<drivers::Sample> out;
  EXPECT_EQ(q.popBatch(out, 100, 10ms), 10u);
  EXPECT_EQ(out.back().seq, 9u);  // the oldest were kept in order
}

TEST(SampleQueue, BlockPolicyLosesNothing) {
  SampleQueue q(64, OverflowPolicy::kBlock);
  std::thread producer([&] {
    for (std::uint32_t i = 0; i < 100; ++i) q.push(run(i * 100, 100));
  });
  std::vector<drivers::Sample> out;
  while (out.size() < 10000) q.popBatch(out, 37, 1000ms);
  producer.join();
  EXPECT_EQ(q.dropped(), 0u);
  for (std::uint32_t i = 0; i < out.size(); ++i) ASSERT_EQ(out[i].seq, i);
}

TEST(SampleQueue, PopTimesOutEmptyAndCloseWakesEveryone) {
  SampleQueue q(4, OverflowPolicy::kBlock);
  std::vector<drivers::Sample> out;
  EXPECT_EQ(q.popBatch(out, 10, 20ms), 0u);
  q.push(run(0, 4));
  std::thread blocked([&] { q.push(run(4, 4)); });  // waits for room
  std::this_thread::sleep_for(20ms);
  q.close();
  blocked.join();
  EXPECT_EQ(q.dropped(), 4u);
}

TEST(WindowStats, MeanSpreadDriftAndBeamLoss) {
  std::vector<drivers::Sample> w(4);
  const double values_mm[] = {10.000, 10.002, 10.004, 10.006};
  for (int i = 0; i < 4; ++i) w[i].value = values_mm[i];
  const auto s = windowStats(w);
  EXPECT_NEAR(s.mean, 10.003, 1e-12);
  EXPECT_NEAR(s.stddev_um, std::sqrt((9.0 + 1.0 + 1.0 + 9.0) / 3.0), 1e-6);  // um
  EXPECT_NEAR(s.drift_um, 4.0, 1e-6);                                        // 10.005 - 10.001 mm
  EXPECT_FALSE(isStable(s, 3.0));
  EXPECT_TRUE(isStable(s, 5.0));
  w[2].beam_ok = false;
  EXPECT_FALSE(isStable(windowStats(w), 100.0));
}

}  // namespace
}  // namespace mtcal::acquisition
