#include "core/threads.h"

#include <omp.h>
#include <torch/torch.h>

#include <algorithm>
#include <cstdlib>
#include <string>
#include <thread>

#include "core/log.h"

namespace ddhgs::core {
namespace {
int g_threads = 0;
}

int configure_threads(int requested) {
  int n = requested;
  const char* source = "--threads";
  if (n <= 0) {
    if (const char* env = std::getenv("DDHGS_THREADS"))
      n = std::atoi(env), source = "DDHGS_THREADS";
  }
  const int cores = std::max(1, int(std::thread::hardware_concurrency()));
  if (n <= 0) n = cores;
  // Far more threads than cores only adds contention: 2000 threads made a
  // 0.1 s render take minutes.
  if (n > kMaxThreadsPerCore * cores) {
    log_warn(std::string(source) + " " + std::to_string(n) + " is more than " +
             std::to_string(kMaxThreadsPerCore) + " threads per core on this machine's " +
             std::to_string(cores) + " cores; using " + std::to_string(kMaxThreadsPerCore * cores));
    n = kMaxThreadsPerCore * cores;
  }
  torch::set_num_threads(n);
  omp_set_num_threads(n);
  g_threads = n;
  return n;
}

int thread_count() {
  if (g_threads == 0) configure_threads(0);
  return g_threads;
}

}  // namespace ddhgs::core
