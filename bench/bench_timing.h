// Timing helper shared by the micro-benchmarks (bench_sh, bench_ssim).
#pragma once
#include <algorithm>
#include <chrono>
#include <vector>

namespace ddhgs::bench {

// Median wall milliseconds of `reps` calls of f, after one untimed warm-up
// call (buffers allocated, pages touched).
template <typename F>
double median_ms(int reps, F&& f) {
  using Clock = std::chrono::steady_clock;
  f();
  std::vector<double> ms;
  for (int r = 0; r < reps; ++r) {
    const auto t = Clock::now();
    f();
    ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t).count());
  }
  std::sort(ms.begin(), ms.end());
  return ms[ms.size() / 2];
}

}  // namespace ddhgs::bench
