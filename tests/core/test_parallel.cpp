// core::parallel_for: every index exactly once, chunks of at least the grain,
// the same chunks whichever threads run them, inline when nested, the first
// exception passed on, and two callers at once.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

#include "core/parallel.h"
#include "core/threads.h"

using namespace ddhgs;

namespace {

struct ThreadsFor {
  int before = core::thread_count();
  explicit ThreadsFor(int n) { core::configure_threads(n); }
  ~ThreadsFor() { core::configure_threads(before); }
};

std::vector<std::pair<int64_t, int64_t>> chunks_of(int64_t begin, int64_t end, int64_t grain) {
  std::mutex mutex;
  std::vector<std::pair<int64_t, int64_t>> chunks;
  core::parallel_for(begin, end, grain, [&](int64_t b, int64_t e) {
    std::lock_guard<std::mutex> lock(mutex);
    chunks.emplace_back(b, e);
  });
  std::sort(chunks.begin(), chunks.end());
  return chunks;
}

TEST(Parallel, CoversEveryIndexOnceInChunksOfAtLeastTheGrain) {
  ThreadsFor threads(3);
  for (int64_t n : {0, 1, 7, 64, 1000, 100003}) {
    for (int64_t grain : {1, 16, 4096}) {
      std::vector<std::atomic<int>> hits(size_t(n) + 1);
      core::parallel_for(5, 5 + n, grain, [&](int64_t b, int64_t e) {
        for (int64_t i = b; i < e; ++i) hits[size_t(i - 5)]++;
      });
      for (int64_t i = 0; i < n; ++i) ASSERT_EQ(hits[size_t(i)].load(), 1) << n << " " << grain;
      const auto chunks = chunks_of(5, 5 + n, grain);
      for (size_t c = 0; c + 1 < chunks.size(); ++c) {
        EXPECT_EQ(chunks[c].second, chunks[c + 1].first);
        EXPECT_GE(chunks[c].second - chunks[c].first, grain);
      }
      EXPECT_LE(int64_t(chunks.size()), core::chunk_count(n, grain, 3));
    }
  }
}

// The chunks (and so any result a chunk computes) depend on the range, the
// grain and the configured count only: the same on every call.
TEST(Parallel, ChunksAreTheSameOnEveryCall) {
  ThreadsFor threads(2);
  const auto first = chunks_of(0, 10007, 64);
  EXPECT_EQ(int64_t(first.size()), core::chunk_count(10007, 64, 2));
  for (int i = 0; i < 50; ++i) ASSERT_EQ(chunks_of(0, 10007, 64), first);
}

TEST(Parallel, UsesSeveralThreadsAndRunsNestedLoopsInline) {
  ThreadsFor threads(2);
  std::mutex mutex;
  std::set<std::thread::id> ids;
  std::atomic<int> inner_calls{0};
  // Long enough chunks that a worker surely wakes before the caller ends.
  core::parallel_for(0, 8, 1, [&](int64_t, int64_t) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      ids.insert(std::this_thread::get_id());
    }
    core::parallel_for(0, 1000, 1, [&](int64_t b, int64_t e) {
      EXPECT_EQ(b, 0);
      EXPECT_EQ(e, 1000);
      inner_calls++;
    });
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  });
  EXPECT_EQ(inner_calls.load(), 8);
  EXPECT_EQ(ids.size(), 2u);
}

TEST(Parallel, PassesTheFirstExceptionOnAfterEveryChunk) {
  ThreadsFor threads(2);
  std::atomic<int> ran{0};
  EXPECT_THROW(core::parallel_for(0, 64, 1,
                                  [&](int64_t b, int64_t e) {
                                    ran += int(e - b);
                                    if (b == 0) throw std::runtime_error("chunk 0");
                                  }),
               std::runtime_error);
  EXPECT_EQ(ran.load(), 64);
  // The pool still works afterwards.
  std::atomic<int64_t> sum{0};
  core::parallel_for(0, 100, 1, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) sum += i;
  });
  EXPECT_EQ(sum.load(), 4950);
}

// Two threads of the caller's own (scene loading does this) each get their
// whole loop done: one on the pool, the other inline.
TEST(Parallel, TwoCallersAtOnce) {
  ThreadsFor threads(2);
  std::atomic<int64_t> sums[2] = {{0}, {0}};
  auto caller = [&](int which) {
    for (int round = 0; round < 200; ++round)
      core::parallel_for(0, 1000, 10, [&](int64_t b, int64_t e) {
        for (int64_t i = b; i < e; ++i) sums[which] += i;
      });
  };
  std::thread a(caller, 0), b(caller, 1);
  a.join();
  b.join();
  EXPECT_EQ(sums[0].load(), 200 * 499500);
  EXPECT_EQ(sums[1].load(), 200 * 499500);
}

TEST(Parallel, ChunkCount) {
  EXPECT_EQ(core::chunk_count(0, 1, 2), 0);
  EXPECT_EQ(core::chunk_count(5, 1, 2), 5);
  EXPECT_EQ(core::chunk_count(1000, 1, 2), 8);
  EXPECT_EQ(core::chunk_count(1000, 300, 2), 4);
  EXPECT_EQ(core::chunk_count(1000, 300, 1), 4);
}

}  // namespace
