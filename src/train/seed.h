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

// Stream ids: 0 initialisation, 2 e + 1 the view order of epoch e, 2 i the
// densification of iteration i, kTermStream + i the loss terms of iteration i
// (and the samplers of the diffusion stage's steps after the Gaussian ones).
// The wavelength encoder's initial weights use stream 1, which it shares with
// epoch 0's view order (different consumers; kept so existing runs reproduce).
constexpr uint64_t kEncoderInitStream = 1;
constexpr uint64_t kTermStream = uint64_t(1) << 40;
// The denoiser U-Net's initial weights (beyond every iteration's term stream).
constexpr uint64_t kDenoiserInitStream = uint64_t(1) << 41;
// The auxiliary models of diffusion.pairs: fold f's run seed; with perturbed,
// also view v's turn (from the auxiliary model's own seed).
constexpr uint64_t kFoldStream = uint64_t(1) << 42;
// kBandStream + i: the bands iteration i measures (loss.bands_per_step).
constexpr uint64_t kBandStream = uint64_t(1) << 43;
// kCropStream + i: the part of its view iteration i measures (loss.view_fraction).
constexpr uint64_t kCropStream = uint64_t(1) << 44;

}  // namespace ddhgs::train
