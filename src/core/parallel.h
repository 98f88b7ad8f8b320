// ddhgs's own parallel loop, for the hand-written hot loops (rasterizer, SH,
// projection, SSIM, Adam, readers).
//
// Why not OpenMP or at::parallel_for: their teams end with a barrier that
// waits until every thread has arrived, so each loop costs a scheduling
// round trip of the slowest thread. When another process competes for the
// cores, a woken worker waits milliseconds for a CPU, and with hundreds of
// loops per training iteration a run beside one busy process took 8x as
// long (docs/benchmarks.md, "Shared machines"). Here a loop ends when its work is
// done: the chunks are claimed from a shared counter, the calling thread
// claims too, and a worker that wakes after the last chunk was claimed finds
// nothing and sleeps again. Nobody waits for a thread that has no work.
//
// The chunks depend only on the range, the grain and the configured thread
// count, never on which thread runs which chunk, so results stay
// bit-identical from run to run, busy machine or not.
#pragma once
#include <cstdint>

namespace ddhgs::core {

namespace detail {
// A type-erased reference to the loop body (no allocation per loop).
struct BodyRef {
  void* object;
  void (*call)(void* object, int64_t begin, int64_t end);
};
void parallel_run(int64_t begin, int64_t end, int64_t grain, BodyRef body);
}  // namespace detail

// Calls body(chunk_begin, chunk_end) over disjoint chunks covering
// [begin, end), each at least `grain` long (but the last), on up to
// core::thread_count() threads. Runs inline when the range is one grain or
// less, on one thread, or inside another parallel_for. The first exception a
// body throws is rethrown here once every chunk has finished.
template <typename F>
void parallel_for(int64_t begin, int64_t end, int64_t grain, const F& body) {
  detail::BodyRef ref{
      const_cast<void*>(static_cast<const void*>(&body)),
      [](void* object, int64_t b, int64_t e) { (*static_cast<const F*>(object))(b, e); }};
  detail::parallel_run(begin, end, grain, ref);
}

// The chunk count parallel_for uses for `items` items of at least `grain`
// each on `threads` threads: a few per thread, so that the threads that
// have a CPU can take over the work of one that has not.
int64_t chunk_count(int64_t items, int64_t grain, int threads);

// Starts (or resizes) the pool's workers for `threads` threads in all;
// called by configure_threads.
void resize_pool(int threads);

}  // namespace ddhgs::core
