#include "core/parallel.h"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

#include "core/threads.h"

namespace ddhgs::core {
namespace {

// Chunks per thread: with 4, the threads that have a CPU take over three
// quarters of a late thread's share.
constexpr int64_t kChunksPerThread = 4;

thread_local bool t_in_parallel = false;

struct Job {
  detail::BodyRef body{};
  int64_t begin = 0, end = 0, size = 1, chunks = 0;
};

// The pool: one job at a time, published under `mutex` with a new
// generation. `claims` holds (generation << 32) | next chunk, so that a worker
// that slept through the end of a job can never claim a chunk of the next
// one with the old body.
class Pool {
 public:
  void resize(int threads) {
    stop();
    for (int i = 1; i < threads; ++i) workers_.emplace_back([this] { work(); });
  }

  // False when another thread's loop is running (the caller then runs inline).
  bool run(const Job& job) {
    std::unique_lock<std::mutex> busy(run_mutex_, std::try_to_lock);
    if (!busy.owns_lock()) return false;
    uint32_t generation;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      generation = ++generation_;
      job_ = job;
      done_ = 0;
      error_ = nullptr;
      claims_ = uint64_t(generation) << 32;
    }
    wake_.notify_all();
    run_chunks(generation, job);
    std::unique_lock<std::mutex> lock(mutex_);
    finished_.wait(lock, [&] { return done_.load() == job.chunks; });
    if (error_) std::rethrow_exception(error_);
    return true;
  }

 private:
  void stop() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = true;
    }
    wake_.notify_all();
    for (auto& worker : workers_) worker.join();
    workers_.clear();
    stopping_ = false;
  }

  void work() {
    flush_denormals();
    uint32_t seen = 0;
    while (true) {
      Job job;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [&] { return stopping_ || generation_ != seen; });
        if (stopping_) return;
        seen = generation_;
        job = job_;
      }
      run_chunks(seen, job);
    }
  }

  bool claim(uint32_t generation, int64_t chunks, int64_t& index) {
    uint64_t state = claims_.load();
    while (true) {
      if (uint32_t(state >> 32) != generation || int64_t(state & 0xffffffffu) >= chunks)
        return false;
      if (claims_.compare_exchange_weak(state, state + 1)) {
        index = int64_t(state & 0xffffffffu);
        return true;
      }
    }
  }

  void run_chunks(uint32_t generation, const Job& job) {
    int64_t index;
    while (claim(generation, job.chunks, index)) {
      const int64_t b = job.begin + index * job.size;
      t_in_parallel = true;
      try {
        job.body.call(job.body.object, b, std::min(job.end, b + job.size));
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex_);
        if (!error_) error_ = std::current_exception();
      }
      t_in_parallel = false;
      if (done_.fetch_add(1) + 1 == job.chunks) {
        std::lock_guard<std::mutex> lock(mutex_);
        finished_.notify_all();
      }
    }
  }

  std::mutex run_mutex_;  // one loop at a time
  std::mutex mutex_;
  std::condition_variable wake_, finished_;
  std::vector<std::thread> workers_;
  bool stopping_ = false;
  uint32_t generation_ = 0;
  Job job_;
  std::atomic<uint64_t> claims_{0};
  std::atomic<int64_t> done_{0};
  std::exception_ptr error_;
};

// Never destroyed: workers may still wait on it while the process exits.
Pool& pool() {
  static Pool* p = new Pool;
  return *p;
}

}  // namespace

int64_t chunk_count(int64_t items, int64_t grain, int threads) {
  if (items <= 0) return 0;
  const int64_t by_grain = (items + std::max<int64_t>(grain, 1) - 1) / std::max<int64_t>(grain, 1);
  return std::max<int64_t>(1, std::min(by_grain, kChunksPerThread * std::max(threads, 1)));
}

void resize_pool(int threads) {
  pool().resize(threads);
}

namespace detail {

void parallel_run(int64_t begin, int64_t end, int64_t grain, BodyRef body) {
  if (begin >= end) return;
  const int threads = thread_count();
  const int64_t items = end - begin;
  if (threads <= 1 || items <= grain || t_in_parallel) {
    body.call(body.object, begin, end);
    return;
  }
  Job job;
  job.body = body;
  job.begin = begin;
  job.end = end;
  const int64_t chunks = chunk_count(items, grain, threads);
  job.size = (items + chunks - 1) / chunks;
  job.chunks = (items + job.size - 1) / job.size;
  if (!pool().run(job)) body.call(body.object, begin, end);
}

}  // namespace detail
}  // namespace ddhgs::core
