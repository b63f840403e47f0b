// A fixed set of worker threads that run one parallel job at a time. The core
// has no threads; this is how the host spreads strips of a frame over cores.
#pragma once

#include <condition_variable>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace camsim::hal {

class ThreadPool {
 public:
  // The caller's thread is worker 0; threads below 1 give 1.
  explicit ThreadPool(int threads);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int size() const { return static_cast<int>(threads_.size()) + 1; }

  // Runs job(worker) once on every worker (0 .. size()-1) and waits for all.
  // job must not throw on workers 1 and up (std::thread ends the program).
  void Run(const std::function<void(int worker)>& job);

 private:
  void Loop(int worker);
  void Stop();  // ends and joins the workers

  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable start_, done_;
  const std::function<void(int)>* job_ = nullptr;
  unsigned generation_ = 0;
  int pending_ = 0;
  bool stop_ = false;
};

}  // namespace camsim::hal
