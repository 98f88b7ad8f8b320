#include "core/threads.h"

#include <omp.h>
#include <torch/torch.h>

#include <cstdlib>
#include <thread>

namespace ddhgs::core {
namespace {
int g_threads = 0;
}

int configure_threads(int requested) {
  int n = requested;
  if (n <= 0) {
    if (const char* env = std::getenv("DDHGS_THREADS")) n = std::atoi(env);
  }
  if (n <= 0) n = int(std::thread::hardware_concurrency());
  if (n <= 0) n = 1;
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
