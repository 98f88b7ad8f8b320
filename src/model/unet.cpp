#include "model/unet.h"

#include <torch/nn/functional/padding.h>
#include <torch/nn/functional/upsampling.h>
#include <torch/nn/modules/activation.h>
#include <torch/nn/modules/linear.h>

#include <cmath>
#include <numeric>

#include "core/error.h"

namespace ddhgs::model {

namespace F = torch::nn::functional;

namespace {

torch::nn::Conv2d conv3x3(int64_t in, int64_t out, int64_t stride = 1) {
  return torch::nn::Conv2d(torch::nn::Conv2dOptions(in, out, 3).stride(stride).padding(1));
}

torch::nn::GroupNorm group_norm(int64_t channels) {
  return torch::nn::GroupNorm(torch::nn::GroupNormOptions(group_count(channels), channels));
}

// Pre-activation residual block; the time embedding enters as a per-channel
// shift between the two convolutions so every level knows the noise level.
class ResBlockImpl : public torch::nn::Module {
 public:
  ResBlockImpl(int64_t in, int64_t out, int64_t emb_dim)
      : norm1_(register_module("norm1", group_norm(in))),
        conv1_(register_module("conv1", conv3x3(in, out))),
        emb_(register_module("emb", torch::nn::Linear(emb_dim, out))),
        norm2_(register_module("norm2", group_norm(out))),
        conv2_(register_module("conv2", conv3x3(out, out))) {
    if (in != out)
      skip_ = register_module("skip", torch::nn::Conv2d(torch::nn::Conv2dOptions(in, out, 1)));
  }

  torch::Tensor forward(const torch::Tensor& x,      // [B, C_in, H, W]
                        const torch::Tensor& emb) {  // [B, E]
    auto h = conv1_(torch::silu(norm1_(x)));
    h = h + emb_(torch::silu(emb)).unsqueeze(-1).unsqueeze(-1);
    h = conv2_(torch::silu(norm2_(h)));
    return (skip_ ? skip_(x) : x) + h;
  }

 private:
  torch::nn::GroupNorm norm1_;
  torch::nn::Conv2d conv1_;
  torch::nn::Linear emb_;
  torch::nn::GroupNorm norm2_;
  torch::nn::Conv2d conv2_;
  torch::nn::Conv2d skip_{nullptr};
};
TORCH_MODULE(ResBlock);

// Single-head self-attention over all pixels of the lowest resolution.
class AttentionImpl : public torch::nn::Module {
 public:
  explicit AttentionImpl(int64_t channels)
      : norm_(register_module("norm", group_norm(channels))),
        qkv_(register_module(
            "qkv", torch::nn::Conv2d(torch::nn::Conv2dOptions(channels, 3 * channels, 1)))),
        proj_(register_module(
            "proj", torch::nn::Conv2d(torch::nn::Conv2dOptions(channels, channels, 1)))) {}

  torch::Tensor forward(const torch::Tensor& x) {  // [B, C, H, W]
    const int64_t b = x.size(0), c = x.size(1), h = x.size(2), w = x.size(3);
    auto qkv = qkv_(norm_(x)).reshape({b, 3, c, h * w});
    auto q = qkv.select(1, 0), k = qkv.select(1, 1), v = qkv.select(1, 2);  // [B, C, P]
    auto weights = torch::softmax(torch::bmm(q.transpose(1, 2), k) / std::sqrt(double(c)), -1);
    auto out = torch::bmm(v, weights.transpose(1, 2)).reshape({b, c, h, w});  // [B, C, H, W]
    return x + proj_(out);
  }

 private:
  torch::nn::GroupNorm norm_;
  torch::nn::Conv2d qkv_, proj_;
};
TORCH_MODULE(Attention);

// A strided convolution rather than pooling, so the network learns what to keep.
class DownsampleImpl : public torch::nn::Module {
 public:
  explicit DownsampleImpl(int64_t channels)
      : conv_(register_module("conv", conv3x3(channels, channels, 2))) {}
  torch::Tensor forward(const torch::Tensor& x) { return conv_(x); }

 private:
  torch::nn::Conv2d conv_;
};
TORCH_MODULE(Downsample);

// Nearest-neighbour upsampling then a convolution: no checkerboard artefacts.
class UpsampleImpl : public torch::nn::Module {
 public:
  explicit UpsampleImpl(int64_t channels)
      : conv_(register_module("conv", conv3x3(channels, channels))) {}
  torch::Tensor forward(const torch::Tensor& x) {
    return conv_(F::interpolate(x, F::InterpolateFuncOptions()
                                       .scale_factor(std::vector<double>{2.0, 2.0})
                                       .mode(torch::kNearest)));
  }

 private:
  torch::nn::Conv2d conv_;
};
TORCH_MODULE(Upsample);

int64_t time_input_dim(const UNetOptions& o) {
  return o.base_channels + o.base_channels % 2;
}
int64_t time_embedding_dim(const UNetOptions& o) {
  return 4 * o.base_channels;
}

}  // namespace

int64_t group_count(int64_t channels) {
  const int64_t cap = std::max<int64_t>(1, std::min<int64_t>(32, channels / 4));
  for (int64_t g = cap; g > 1; --g)
    if (channels % g == 0) return g;
  return 1;
}

void UNetOptions::validate(const std::string& where) const {
  core::require(bands >= 1, where + ": denoiser band count must be >= 1");
  core::require(
      base_channels >= 1 && base_channels <= 1024,
      where + ": base_channels must be in [1, 1024], got " + std::to_string(base_channels));
  core::require(!channel_multipliers.empty() && channel_multipliers.size() <= 6,
                where + ": channel_multipliers must list 1 to 6 levels");
  for (int64_t m : channel_multipliers)
    core::require(m >= 1 && m <= 16, where + ": channel_multipliers entries must be in [1, 16]");
  core::require(blocks_per_level >= 1 && blocks_per_level <= 8,
                where + ": blocks_per_level must be in [1, 8]");
}

int64_t UNetOptions::size_multiple() const {
  return int64_t(1) << (channel_multipliers.size() - 1);
}

UNetOptions unet_options_from_json(const nlohmann::json& preset, const std::string& where,
                                   UNetOptions defaults) {
  UNetOptions o = std::move(defaults);
  auto read = [&](const char* key, auto& value) {
    if (!preset.contains(key)) return;
    try {
      preset.at(key).get_to(value);
    } catch (const nlohmann::json::exception&) {
      throw core::Error(where + ": key '" + key + "' has the wrong type");
    }
  };
  read("base_channels", o.base_channels);
  read("channel_multipliers", o.channel_multipliers);
  read("blocks_per_level", o.blocks_per_level);
  read("attention", o.attention);
  o.validate(where);
  return o;
}

nlohmann::json unet_options_to_json(const UNetOptions& o) {
  return {{"bands", o.bands},
          {"base_channels", o.base_channels},
          {"channel_multipliers", o.channel_multipliers},
          {"blocks_per_level", o.blocks_per_level},
          {"attention", o.attention}};
}

torch::Tensor timestep_embedding(const torch::Tensor& t, int64_t dim) {
  const int64_t half = dim / 2;
  auto options = torch::TensorOptions().dtype(torch::kFloat32).device(t.device());
  // Periods from 2 pi to 2 pi * 10000 steps: fine and coarse step differences
  // are both visible to the MLP.
  auto freqs = torch::exp(torch::arange(half, options) * (-std::log(10000.0) / double(half)));
  auto args = t.to(torch::kFloat32).unsqueeze(1) * freqs.unsqueeze(0);  // [B, half]
  auto emb = torch::cat({torch::sin(args), torch::cos(args)}, 1);
  if (dim % 2 == 1) emb = F::pad(emb, F::PadFuncOptions({0, 1}));
  return emb;
}

UNetImpl::UNetImpl(const UNetOptions& options) : options_(options) {
  options_.validate("denoiser options");
  const int64_t base = options_.base_channels;
  const int64_t emb_dim = time_embedding_dim(options_);
  const int64_t levels = int64_t(options_.channel_multipliers.size());

  time_mlp_ = register_module(
      "time_mlp", torch::nn::Sequential(torch::nn::Linear(time_input_dim(options_), emb_dim),
                                        torch::nn::SiLU(), torch::nn::Linear(emb_dim, emb_dim)));
  input_conv_ = register_module("input_conv", conv3x3(2 * options_.bands, base));

  down_ = register_module("down", torch::nn::ModuleList());
  std::vector<int64_t> skip_channels = {base};
  int64_t ch = base;
  for (int64_t level = 0; level < levels; ++level) {
    const int64_t out = base * options_.channel_multipliers[level];
    for (int64_t b = 0; b < options_.blocks_per_level; ++b) {
      down_->push_back(ResBlock(ch, out, emb_dim));
      ch = out;
      skip_channels.push_back(ch);
    }
    if (level + 1 < levels) {
      down_->push_back(Downsample(ch));
      skip_channels.push_back(ch);
    }
  }

  middle_ = register_module("middle", torch::nn::ModuleList());
  middle_->push_back(ResBlock(ch, ch, emb_dim));
  if (options_.attention) middle_->push_back(Attention(ch));
  middle_->push_back(ResBlock(ch, ch, emb_dim));

  up_ = register_module("up", torch::nn::ModuleList());
  for (int64_t level = levels - 1; level >= 0; --level) {
    const int64_t out = base * options_.channel_multipliers[level];
    for (int64_t b = 0; b <= options_.blocks_per_level; ++b) {
      up_->push_back(ResBlock(ch + skip_channels.back(), out, emb_dim));
      skip_channels.pop_back();
      ch = out;
    }
    if (level > 0) up_->push_back(Upsample(ch));
  }

  output_norm_ = register_module("output_norm", group_norm(ch));
  output_conv_ = register_module("output_conv", conv3x3(ch, options_.bands));
  // A zero last layer starts the model at predicting zero noise, so early
  // joint training is not disturbed by large random gradients into the render.
  torch::NoGradGuard no_grad;
  output_conv_->weight.zero_();
  output_conv_->bias.zero_();
}

torch::Tensor UNetImpl::forward(const torch::Tensor& x_t, const torch::Tensor& cond,
                                const torch::Tensor& t) {
  TORCH_CHECK(x_t.dim() == 4 && x_t.size(1) == options_.bands, "UNet: x_t must be [B, ",
              options_.bands, ", H, W], got ", x_t.sizes());
  TORCH_CHECK(cond.sizes() == x_t.sizes(), "UNet: cond ", cond.sizes(), " must match x_t ",
              x_t.sizes());
  TORCH_CHECK(t.dim() == 1 && t.size(0) == x_t.size(0), "UNet: t must be [B]");
  const int64_t h = x_t.size(2), w = x_t.size(3), m = options_.size_multiple();
  const int64_t pad_h = (m - h % m) % m, pad_w = (m - w % m) % m;
  auto x = torch::cat({x_t, cond}, 1);
  if (pad_h || pad_w)
    x = F::pad(x, F::PadFuncOptions({0, pad_w, 0, pad_h}).mode(torch::kReplicate));
  auto emb = time_mlp_->forward(timestep_embedding(t, time_input_dim(options_)).to(x.dtype()));
  auto out = forward_padded(x, emb);
  if (pad_h || pad_w) out = out.slice(2, 0, h).slice(3, 0, w);
  return out;
}

torch::Tensor UNetImpl::forward_padded(const torch::Tensor& x, const torch::Tensor& emb) {
  std::vector<torch::Tensor> skips;
  auto h = input_conv_(x);
  skips.push_back(h);
  for (const auto& layer : *down_) {
    if (auto* block = layer->as<ResBlockImpl>())
      h = block->forward(h, emb);
    else
      h = layer->as<DownsampleImpl>()->forward(h);
    skips.push_back(h);
  }
  for (const auto& layer : *middle_) {
    if (auto* block = layer->as<ResBlockImpl>())
      h = block->forward(h, emb);
    else
      h = layer->as<AttentionImpl>()->forward(h);
  }
  for (const auto& layer : *up_) {
    if (auto* block = layer->as<ResBlockImpl>()) {
      h = block->forward(torch::cat({h, skips.back()}, 1), emb);
      skips.pop_back();
    } else {
      h = layer->as<UpsampleImpl>()->forward(h);
    }
  }
  return output_conv_(torch::silu(output_norm_(h)));
}

void save_unet(torch::serialize::OutputArchive& archive, const std::string& key, UNet& unet) {
  torch::serialize::OutputArchive sub(archive.compilation_unit());
  sub.write("options_json", c10::IValue(unet_options_to_json(unet->options()).dump()));
  unet->save(sub);
  archive.write(key, sub);
}

UNet load_unet(torch::serialize::InputArchive& archive, const std::string& key,
               const std::filesystem::path& file) {
  torch::serialize::InputArchive sub;
  core::require(archive.try_read(key, sub), file, "no denoiser '" + key + "' in the checkpoint");
  c10::IValue options_json;
  core::require(sub.try_read("options_json", options_json) && options_json.isString(), file,
                "denoiser '" + key + "' has no options");
  UNetOptions options;
  try {
    auto j = nlohmann::json::parse(options_json.toStringRef());
    UNetOptions stored;
    stored.bands = j.at("bands").get<int64_t>();
    options = unet_options_from_json(j, file.string(), stored);
  } catch (const nlohmann::json::exception& e) {
    throw core::Error(file, "denoiser options are not valid JSON: " + core::message_of(e));
  }
  UNet unet(options);
  try {
    unet->load(sub);
  } catch (const c10::Error& e) {
    const std::string what = e.what_without_backtrace();
    throw core::Error(file, "denoiser '" + key + "' tensors do not match its options: " +
                                what.substr(0, what.find('\n')));
  }
  return unet;
}

}  // namespace ddhgs::model
