#include "hal/thread_pool.h"

namespace camsim::hal {

ThreadPool::ThreadPool(int threads) {
  try {
    for (int i = 1; i < threads; ++i) threads_.emplace_back([this, i] { Loop(i); });
  } catch (...) {  // a thread could not start: the ones that did must not outlive the pool
    Stop();
    throw;
  }
}

ThreadPool::~ThreadPool() { Stop(); }

void ThreadPool::Stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  start_.notify_all();
  for (std::thread& t : threads_) t.join();
  threads_.clear();
}

void ThreadPool::Run(const std::function<void(int)>& job) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    job_ = &job;
    pending_ = static_cast<int>(threads_.size());
    ++generation_;
  }
  start_.notify_all();
  // The other workers hold a pointer to `job`: they finish before Run
  // returns, also when worker 0's part throws.
  struct WaitForWorkers {
    ThreadPool* pool;
    ~WaitForWorkers() {
      std::unique_lock<std::mutex> lock(pool->mutex_);
      pool->done_.wait(lock, [this] { return pool->pending_ == 0; });
      pool->job_ = nullptr;
    }
  } wait{this};
  job(0);
}

void ThreadPool::Loop(int worker) {
  unsigned seen = 0;
  for (;;) {
    const std::function<void(int)>* job;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      start_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
      job = job_;
    }
    (*job)(worker);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (--pending_ == 0) done_.notify_one();
    }
  }
}

}  // namespace camsim::hal
