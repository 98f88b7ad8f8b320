// Thread set-up: LibTorch defaults to one intra-op thread on small machines.
#pragma once

namespace ddhgs::core {

// More threads than this per core are capped (with a warning).
constexpr int kMaxThreadsPerCore = 4;

// Sets LibTorch's intra-op threads and OpenMP's thread count. requested <= 0
// means: $DDHGS_THREADS if set, else the number of cores. At most
// kMaxThreadsPerCore per core. Returns the count.
int configure_threads(int requested = 0);

// Threads the renderer and other hand-written parallel loops should use.
int thread_count();

}  // namespace ddhgs::core
