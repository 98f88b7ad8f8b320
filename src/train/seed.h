// Seeds for training's random draws.
#pragma once
#include <cstdint>

namespace ddhgs::train {

// Mixes a seed with a stream id (splitmix64): every random draw of training
// depends only on (seed, stream), never on what was drawn before.
inline uint64_t mix_seed(uint64_t seed, uint64_t stream) {
  uint64_t z = seed + 0x9e3779b97f4a7c15ULL * (stream + 1);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

}  // namespace ddhgs::train
