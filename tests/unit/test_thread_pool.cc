// hal::ThreadPool: the host's workers for the strips of a frame.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>
#include <vector>

#include "hal/thread_pool.h"

namespace camsim::hal {
namespace {

TEST(ThreadPool, EveryWorkerRunsOnceAndRunWaitsForAll) {
  for (int threads : {1, 2, 5}) {
    ThreadPool pool(threads);
    ASSERT_EQ(pool.size(), threads);
    for (int round = 0; round < 20; ++round) {
      std::vector<std::atomic<int>> runs(static_cast<size_t>(threads));
      pool.Run([&](int worker) {
        std::this_thread::sleep_for(std::chrono::microseconds(worker * 200));  // the last ones finish last
        ++runs[static_cast<size_t>(worker)];
      });
      for (int w = 0; w < threads; ++w) EXPECT_EQ(runs[static_cast<size_t>(w)], 1) << threads << " threads, " << w;
    }
  }
}

TEST(ThreadPool, FewerThanOneThreadIsOne) {
  EXPECT_EQ(ThreadPool(0).size(), 1);
  EXPECT_EQ(ThreadPool(-3).size(), 1);
}

// The other workers read the job Run was given: when worker 0's part throws,
// Run still waits for them before the exception leaves it, and the pool runs
// the next job.
TEST(ThreadPool, AThrowOnTheCallersWorkerWaitsForTheOthers) {
  ThreadPool pool(3);
  std::atomic<int> finished{0};
  EXPECT_THROW(pool.Run([&](int worker) {
    if (worker == 0) throw std::runtime_error("worker 0");
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    ++finished;
  }),
               std::runtime_error);
  EXPECT_EQ(finished, 2) << "Run returned before its workers";
  std::atomic<int> again{0};
  pool.Run([&](int) { ++again; });
  EXPECT_EQ(again, 3);
}

}  // namespace
}  // namespace camsim::hal
