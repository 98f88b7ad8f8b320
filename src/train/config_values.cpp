// The values a config may hold, beyond their types (config.cpp checks those):
// a nonsense value ends the command before any work, naming the key, instead
// of training on it (a zero divisor made every SH coefficient infinite) or
// failing only when the run is written out (an SH degree the PLY cannot hold).
#include <cmath>
#include <limits>

#include "core/error.h"
#include "train/config.h"

namespace ddhgs::train {

namespace {

using nlohmann::json;

constexpr double kInf = std::numeric_limits<double>::infinity();

struct Range {
  const char* key;  // dotted path
  double min, max;  // bounds
  bool above_min;   // min itself excluded
  bool integer = false;
};

// Diffusion keys are checked where they are read (train/diffusion_term.cpp).
constexpr Range kRanges[] = {
    {"iterations", 1, kInf, false, true},
    {"seed", 0, kInf, false, true},
    {"data.downscale", 1, kInf, false, true},
    {"data.bin", 1, kInf, false, true},
    {"data.cache_mb", 0, kInf, false, true},
    {"model.sh_degree", 0, 3, false, true},
    {"model.sh_degree_every", 0, kInf, false, true},
    {"init.random_points", 1, kInf, false, true},
    {"init.extra_random_per_pixel", 0, kInf, false},
    {"init.opacity", 0, 1, true},
    {"init.neighbours", 1, kInf, false, true},
    {"init.colour_views", 1, kInf, false, true},
    {"optim.means_lr_init", 0, kInf, false},
    {"optim.means_lr_final", 0, kInf, false},
    {"optim.means_lr_max_steps", 1, kInf, false, true},
    {"optim.sh_dc_lr", 0, kInf, false},
    {"optim.sh_rest_lr_divisor", 0, kInf, true},
    {"optim.opacity_lr", 0, kInf, false},
    {"optim.scaling_lr", 0, kInf, false},
    {"optim.rotation_lr", 0, kInf, false},
    {"optim.adam_eps", 0, kInf, true},
    {"optim.background_lr", 0, kInf, false},
    {"loss.l1", 0, kInf, false},
    {"loss.dssim", 0, kInf, false},
    {"loss.spectral", 0, kInf, false},
    {"loss.spectral_temperature", 0, kInf, true},
    {"densify.from_iter", 0, kInf, false, true},
    {"densify.until_iter", 0, kInf, false, true},
    {"densify.every", 0, kInf, false, true},
    {"densify.grad_threshold", 0, kInf, false},
    {"densify.percent_dense", 0, kInf, false},
    {"densify.opacity_reset_every", 0, kInf, false, true},
    {"densify.min_opacity", 0, 1, false},
    {"densify.max_screen_px", 0, kInf, false},
    {"densify.max_world_fraction", 0, kInf, false},
    {"densify.max_gaussians", 0, kInf, false, true},
    {"output.log_every", 0, kInf, false, true},
    {"output.checkpoint_every", 0, kInf, false, true},
};

const json* find_key(const json& config, const std::string& dotted) {
  const json* node = &config;
  size_t start = 0;
  while (true) {
    const size_t dot = dotted.find('.', start);
    const std::string key = dotted.substr(start, dot == std::string::npos ? dot : dot - start);
    if (!node->is_object() || !node->contains(key)) return nullptr;
    node = &node->at(key);
    if (dot == std::string::npos) return node;
    start = dot + 1;
  }
}

std::string bound_text(double value) {
  if (std::isinf(value)) return "";
  const auto integer = static_cast<long long>(value);
  return double(integer) == value ? std::to_string(integer) : std::to_string(value);
}

std::string wanted(const Range& r) {
  std::string kind = r.integer ? "an integer" : "a number";
  std::string lower = std::string(r.above_min ? " > " : " >= ") + bound_text(r.min);
  if (std::isinf(r.max)) return kind + lower;
  return kind + lower + " and <= " + bound_text(r.max);
}

void check_range(const Range& r, const json& value, const std::string& source) {
  if (!value.is_number()) return;  // types are checked apart
  const double v = value.get<double>();
  const bool ok = std::isfinite(v) && (r.above_min ? v > r.min : v >= r.min) && v <= r.max &&
                  (!r.integer || v == std::floor(v));
  if (!ok)
    throw core::Error(source, "key '" + std::string(r.key) + "' is " +
                                  (std::isfinite(v) ? value.dump() : std::to_string(v)) +
                                  ", expected " + wanted(r));
}

}  // namespace

void check_config_values(const json& config, const std::string& source) {
  for (const Range& r : kRanges)
    if (const json* value = find_key(config, r.key)) check_range(r, *value, source);
}

void check_config_value(const std::string& key, const json& value, const std::string& source) {
  for (const Range& r : kRanges)
    if (key == r.key) check_range(r, value, source);
}

}  // namespace ddhgs::train
