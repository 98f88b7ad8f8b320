#include "core/threads.h"

#include <ATen/Parallel.h>
#include <omp.h>
#include <xmmintrin.h>

#include <cstdlib>
#include <sstream>

#include "core/cpu_budget.h"
#include "core/log.h"
#include "core/parallel.h"

namespace ddhgs::core {
namespace {
int g_threads = 0;
std::string g_source;
CpuBudget g_budget;

}  // namespace

// Denormal floats (tiny Adam moments as they decay, the U-Net's activations)
// cost a hundred cycles each on x86; nothing here needs them. The flags are
// per thread: set on the caller and on every worker of every pool.
void flush_denormals() {
  _mm_setcsr(_mm_getcsr() | 0x8040);  // FTZ | DAZ
}

void set_pool_environment() {
  // PASSIVE: a worker that finds no work sleeps at once. libgomp's default
  // spins 300,000 PAUSE instructions first (about 15 ms here), so at every
  // barrier a finished thread holds a core its descheduled team-mate needs.
  setenv("OMP_WAIT_POLICY", "PASSIVE", 0);
  // OpenBLAS's own pthread pool, sized by the machine, spins for ~0.1 s
  // after each product and so takes the cores from the OpenMP team; the
  // products run inside the team's regions or between them, on one thread.
  setenv("OPENBLAS_NUM_THREADS", "1", 0);
}

int configure_threads(int requested) {
  g_budget = cpu_budget();
  int n = requested;
  std::string source = "--threads";
  if (n <= 0) {
    if (const char* env = std::getenv("DDHGS_THREADS"))
      n = std::atoi(env), source = "DDHGS_THREADS";
  }
  if (n <= 0) n = g_budget.cpus, source = g_budget.source;
  // Far more threads than CPUs only adds contention: 2000 threads made a
  // 0.1 s render take minutes.
  const int cap = kMaxThreadsPerCore * g_budget.cpus;
  if (n > cap) {
    log_warn(source + " " + std::to_string(n) + " is more than " +
             std::to_string(kMaxThreadsPerCore) + " threads per CPU on the " +
             std::to_string(g_budget.cpus) + " CPUs this process may use; using " +
             std::to_string(cap));
    n = cap;
  }
  flush_denormals();
  at::set_num_threads(1);
  // OpenMP's workers start here, so that each flushes denormals too.
#pragma omp parallel num_threads(n)
  flush_denormals();
  omp_set_num_threads(1);
  g_threads = n;
  g_source = source;
  resize_pool(n);
  return n;
}

int thread_count() {
  if (g_threads == 0) configure_threads(0);
  return g_threads;
}

// OpenMP's count is what LibTorch's at::get_num_threads() and oneDNN read.
TorchThreads::TorchThreads() : before_(omp_get_max_threads()) {
  omp_set_num_threads(thread_count());
}

TorchThreads::~TorchThreads() {
  omp_set_num_threads(before_);
}

const std::string& thread_source() {
  thread_count();
  return g_source;
}

std::string thread_summary() {
  thread_count();
  std::ostringstream s;
  s << g_threads << (g_threads == 1 ? " thread" : " threads") << " (" << g_source << "; "
    << g_budget.affinity << " of " << g_budget.machine << " cores in the affinity mask";
  if (g_budget.quota) s << ", cgroup quota " << *g_budget.quota << " CPUs";
  s << ")";
  return s.str();
}

}  // namespace ddhgs::core
