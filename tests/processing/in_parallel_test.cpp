// Work spread over the cores (processing/src/in_parallel.h), and the diagnosis' fits made so: the
// same numbers, bit for bit, as on one thread.
#include "in_parallel.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <atomic>
#include <chrono>
#include <cmath>
#include <random>
#include <stdexcept>
#include <thread>
#include <vector>

#include "diagnosis_internal.h"

namespace mtcal::processing::detail {
namespace {

TEST(InParallel, DoesEveryItemOnceAndReportsOnTheCallingThread) {
  constexpr std::size_t kItems = 1000;
  std::vector<std::atomic<int>> times(kItems);
  const auto caller = std::this_thread::get_id();
  std::size_t last_done = 0;
  bool done_elsewhere = false, done_backwards = false;
  inParallel(
      kItems, [&](std::size_t k) { ++times[k]; },
      [&](std::size_t done) {
        done_elsewhere = done_elsewhere || std::this_thread::get_id() != caller;
        done_backwards = done_backwards || done <= last_done || done > kItems;
        last_done = done;
      });
  for (std::size_t k = 0; k < kItems; ++k) EXPECT_EQ(times[k], 1) << "item " << k;
  EXPECT_FALSE(done_elsewhere);
  EXPECT_FALSE(done_backwards);
  EXPECT_GT(last_done, 0U);
  inParallel(0, [&](std::size_t) { FAIL() << "no item to do"; });
}

TEST(InParallel, ThrowsTheFirstFailureOnceEveryThreadHasStopped) {
  // As a loop would: the first item's to fail, every item before it done, none after it begun
  // but those under way.
  std::vector<std::atomic<int>> times(100);
  try {
    inParallel(100, [&](std::size_t k) {
      ++times[k];
      if (k >= 30 && k % 10 == 0) throw std::runtime_error(fmt::format("item {}", k));
    });
    ADD_FAILURE() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "item 30");
  }
  for (std::size_t k = 0; k <= 30; ++k) EXPECT_EQ(times[k], 1) << "item " << k;
  // A progress display that stops the work (a cancelled diagnosis) is such a failure too.
  EXPECT_THROW(inParallel(
                   100, [](std::size_t) {}, [](std::size_t) { throw std::runtime_error("cancelled"); }),
               std::runtime_error);
}

TEST(InParallel, WorkInsideWorkSpreadsOntoTheCoresOthersLeft) {
  // Two items: the first done at once, the second waits for its thread to be given back, then
  // spreads its own two items, each of which waits for the other to begin: on one thread they
  // would wait for ever (the bound only keeps a broken build from hanging).
  const bool cores = std::thread::hardware_concurrency() >= 2;
  std::atomic<bool> first_done{false};
  std::atomic<int> began{0};
  bool both_began = false;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  inParallel(2, [&](std::size_t k) {
    if (k == 0) {
      first_done = true;
      return;
    }
    while (!first_done || spareThreads() < 1) {
      if (std::chrono::steady_clock::now() > deadline) return;
      std::this_thread::yield();
    }
    inParallel(2, [&](std::size_t) {
      ++began;
      while (began < 2 && std::chrono::steady_clock::now() < deadline) std::this_thread::yield();
    });
    both_began = began == 2;
  });
  if (cores) {
    EXPECT_TRUE(both_began) << "the inner items did not run side by side";
  }
  // Every thread given back.
  EXPECT_EQ(spareThreads(),
            static_cast<int>(std::min<std::size_t>(std::thread::hardware_concurrency(), kMostThreads)) - 1);
}

TEST(InParallel, NoMoreThreadsWorkThanCores) {
  std::atomic<int> working{0}, most{0};
  inParallel(8, [&](std::size_t) {
    inParallel(8, [&](std::size_t) {
      const int now = ++working;
      for (int seen = most.load(); now > seen && !most.compare_exchange_weak(seen, now);) {
      }
      volatile double sink = 0.0;
      for (int i = 0; i < 20000; ++i) sink = sink + std::sqrt(static_cast<double>(i));
      --working;
    });
  });
  EXPECT_LE(most,
            static_cast<int>(std::min<std::size_t>(std::max(1u, std::thread::hardware_concurrency()), kMostThreads)));
  EXPECT_GE(most, 1);
}

TEST(InParallel, OneThreadKeepsTheWorkHere) {
  const OneThread here;
  const auto caller = std::this_thread::get_id();
  int elsewhere = 0;  // written on this thread alone, or the test fails under a sanitizer too
  inParallel(16, [&](std::size_t) { elsewhere += std::this_thread::get_id() != caller; });
  EXPECT_EQ(elsewhere, 0);
}

/// A fit, or a cross-validation, made on one thread (OneThread; on a machine of one core
/// everything is).
template <class Make>
auto onOneThread(const Make& make) {
  const OneThread here;
  return make();
}

TEST(InParallel, FitsAndHeldOutResidualsAreTheSameAsOnOneThread) {
  // Tall enough to be reduced in blocks of rows (20 000 rows: 40 blocks), in 5 folds.
  constexpr Eigen::Index kRows = 20000, kColumns = 12;
  std::mt19937_64 rng(5);
  std::normal_distribution<double> normal;
  Eigen::MatrixXd x(kRows, kColumns);
  for (Eigen::Index j = 0; j < kColumns; ++j)
    for (Eigen::Index i = 0; i < kRows; ++i) x(i, j) = normal(rng) + std::sin(0.001 * static_cast<double>(i * (j + 1)));
  Eigen::VectorXd y = x * Eigen::VectorXd::LinSpaced(kColumns, -1.0, 2.0);
  for (Eigen::Index i = 0; i < kRows; ++i) y(i) += 0.1 * normal(rng);
  Eigen::VectorXi fold(kRows);
  for (Eigen::Index i = 0; i < kRows; ++i) fold(i) = static_cast<int>(i * 5 / kRows);

  const auto spread = leastSquares(x, y);
  const auto alone = onOneThread([&] { return leastSquares(x, y); });
  EXPECT_EQ(spread.rank, kColumns);
  EXPECT_TRUE((spread.coefficients.array() == alone.coefficients.array()).all());
  EXPECT_TRUE((spread.standard_error.array() == alone.standard_error.array()).all());
  EXPECT_EQ(spread.rss, alone.rss);
  // And right: the coefficients within 6 standard errors of the line's.
  EXPECT_LT(
      ((spread.coefficients - Eigen::VectorXd::LinSpaced(kColumns, -1.0, 2.0)).array() / spread.standard_error.array())
          .abs()
          .maxCoeff(),
      6.0);

  const auto held_spread = crossValidate(x, y, fold);
  const auto held_alone = onOneThread([&] { return crossValidate(x, y, fold); });
  EXPECT_TRUE((held_spread.residual.array() == held_alone.residual.array()).all());
  EXPECT_EQ(held_spread.rms, held_alone.rms);
  EXPECT_NEAR(held_spread.rms, 0.1, 0.005);  // the noise, the folds' coefficients all but exact
}

}  // namespace
}  // namespace mtcal::processing::detail
