// The timestep-conditioned U-Net that predicts diffusion noise from a noisy
// hyperspectral image and the Gaussian render it is conditioned on.
#pragma once
#include <torch/nn/module.h>
#include <torch/nn/modules/container/modulelist.h>
#include <torch/nn/modules/container/sequential.h>
#include <torch/nn/modules/conv.h>
#include <torch/nn/modules/normalization.h>
#include <torch/serialize/archive.h>

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/tensor.h"

namespace ddhgs::model {

// Width and depth of the denoiser; the preset keys have the same names.
struct UNetOptions {
  int64_t bands = 1;           // N: channels of the image and of the condition
  int64_t base_channels = 32;  // channels at full resolution
  // One entry per resolution level; level l has base_channels * multiplier[l]
  // channels at 1 / 2^l of the input size.
  std::vector<int64_t> channel_multipliers = {1, 2, 4};
  int64_t blocks_per_level = 1;
  // Self-attention at the lowest resolution. Off by default: its memory is
  // (H W / 4^(levels-1))^2 floats, 1.6 GB for a 640 x 512 view with 3 levels.
  bool attention = false;

  // Throws core::Error naming `where` (a preset file or flag) on bad values.
  void validate(const std::string& where) const;
  // Spatial sizes must be a multiple of this; forward() pads to it.
  int64_t size_multiple() const;
};

// Reads the keys above that are present in `preset` (bands is not a preset
// key: it comes from the data). Throws core::Error naming `where`.
UNetOptions unet_options_from_json(const nlohmann::json& preset, const std::string& where,
                                   UNetOptions defaults = {});
nlohmann::json unet_options_to_json(const UNetOptions& options);

class UNetImpl : public torch::nn::Module {
 public:
  explicit UNetImpl(const UNetOptions& options);

  // Predicted noise [B, N, H, W] for any H, W >= 1 (padded by edge replication
  // to size_multiple() and cropped back). t holds one diffusion step per
  // sample, 0-based, as integers or floats.
  torch::Tensor forward(const torch::Tensor& x_t,   // [B, N, H, W]
                        const torch::Tensor& cond,  // [B, N, H, W]
                        const torch::Tensor& t);    // [B]

  const UNetOptions& options() const { return options_; }

 private:
  torch::Tensor forward_padded(const torch::Tensor& x,       // [B, 2N, H', W']
                               const torch::Tensor& t_emb);  // [B, E]

  UNetOptions options_;
  torch::nn::Sequential time_mlp_{nullptr};
  torch::nn::Conv2d input_conv_{nullptr};
  torch::nn::ModuleList down_{nullptr};  // residual blocks and downsamplers, in order
  torch::nn::ModuleList middle_{nullptr};
  torch::nn::ModuleList up_{nullptr};  // residual blocks and upsamplers, in order
  torch::nn::GroupNorm output_norm_{nullptr};
  torch::nn::Conv2d output_conv_{nullptr};
};
TORCH_MODULE(UNet);

// Sinusoidal embedding of diffusion steps, as in Transformer positions.
torch::Tensor timestep_embedding(const torch::Tensor& t,  // [B]
                                 int64_t dim);            // -> [B, dim]

// GroupNorm group count for `channels`: at most 32 groups, at least 4 channels
// per group where possible, and always a divisor of `channels`.
int64_t group_count(int64_t channels);

// Checkpoint storage: the options and every parameter and buffer under `key`.
void save_unet(torch::serialize::OutputArchive& archive, const std::string& key, UNet& unet);
// Rebuilds the U-Net from its stored options. Throws core::Error naming
// `file` when the key is missing or the tensors do not fit.
UNet load_unet(torch::serialize::InputArchive& archive, const std::string& key,
               const std::filesystem::path& file);

}  // namespace ddhgs::model
