// Thread set-up: how many threads ddhgs's own loops use (sized by the CPUs
// the process may use, not by the machine's cores), and how LibTorch's
// OpenMP, oneDNN and OpenBLAS are kept from competing with them.
#pragma once
#include <string>

namespace ddhgs::core {

// More threads than this per usable CPU are capped (with a warning).
constexpr int kMaxThreadsPerCore = 4;

// The threads: ddhgs's own loops (core/parallel.h) run on thread_count()
// threads. LibTorch's own operators (and OpenMP, oneDNN) run on one thread,
// except inside a TorchThreads scope: their OpenMP teams end in a barrier
// that waits for every thread, which costs a scheduling round trip per
// operator as soon as another process competes for the cores, and the
// Gaussians' tensors are small next to the hand-written loops. Large
// operators (the denoiser's convolutions) run inside the scope.
//
// Sets every pool's thread count and flushes denormals to zero on every
// worker. requested <= 0 means: $DDHGS_THREADS if set, else the CPUs of the
// affinity mask, limited by the cgroup CPU quota (core/cpu_budget.h). At most
// kMaxThreadsPerCore per usable CPU. Returns the count.
int configure_threads(int requested = 0);

// Threads the renderer and other hand-written parallel loops should use.
int thread_count();

// While alive, LibTorch's operators (OpenMP, oneDNN) run on thread_count()
// threads; for large operators such as the denoiser's U-Net, forward and
// backward. Scopes nest; the calling thread's setting only.
class TorchThreads {
 public:
  TorchThreads();
  ~TorchThreads();
  TorchThreads(const TorchThreads&) = delete;
  TorchThreads& operator=(const TorchThreads&) = delete;

 private:
  int before_;
};

// Where the count came from: "--threads", "DDHGS_THREADS", "affinity mask",
// "cgroup quota" or "all cores".
const std::string& thread_source();

// Denormal floats flushed to zero on the calling thread (x86 FTZ and DAZ).
void flush_denormals();

// Runs before any library is initialised (an ELF .preinit_array entry of
// the program: core/early_setup.h), because libgomp and OpenBLAS read their
// settings from the environment once, as they load. Sets, where the user has
// not: OpenMP's idle workers to sleep soon instead of spinning (a spinning
// worker takes the core from the team-mate it waits for as soon as another
// process competes for the CPUs), and OpenBLAS to start no pool of its own.
void set_pool_environment();

// One line for the -v log: "2 threads (all cores; 2 of 2 cores in the
// affinity mask)".
std::string thread_summary();

}  // namespace ddhgs::core
