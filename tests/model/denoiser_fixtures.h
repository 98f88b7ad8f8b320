// Small denoisers shared by the U-Net and diffusion tests.
#pragma once
#include "core/tensor.h"

#include <vector>

#include "model/unet.h"

namespace ddhgs::test {

inline model::UNetOptions tiny_unet_options(int64_t bands,
                                            std::vector<int64_t> multipliers = {1, 2},
                                            bool attention = false) {
  model::UNetOptions o;
  o.bands = bands;
  o.base_channels = 8;
  o.channel_multipliers = std::move(multipliers);
  o.blocks_per_level = 1;
  o.attention = attention;
  return o;
}

// The zero last layer hides everything upstream, so tests that need a live
// network get a seeded one with a random last layer.
inline model::UNet live_unet(const model::UNetOptions& options, uint64_t seed) {
  torch::manual_seed(seed);
  model::UNet unet(options);
  torch::NoGradGuard no_grad;
  for (auto& p : unet->named_parameters())
    if (p.key().rfind("output_conv.", 0) == 0) p.value().normal_(0.0, 0.1);
  return unet;
}

}  // namespace ddhgs::test
