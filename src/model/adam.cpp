#include "model/adam.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "core/parallel.h"

namespace ddhgs::model {

void fused_adam_update(float* param, const float* grad, float* exp_avg, float* exp_avg_sq,
                       int64_t n, double lr, int64_t step, const AdamOptions& options) {
  const float beta1 = float(options.beta1), beta2 = float(options.beta2);
  const float one_minus_beta1 = 1.0f - beta1, one_minus_beta2 = 1.0f - beta2;
  const double bias1 = 1.0 - std::pow(options.beta1, double(step));
  const double bias2 = 1.0 - std::pow(options.beta2, double(step));
  const float step_size = float(lr / bias1);
  const float inv_sqrt_bias2 = float(1.0 / std::sqrt(bias2));
  const float eps = float(options.eps);
  // Large grains: the loop is memory bound and tiny chunks only add overhead.
  core::parallel_for(0, n, 1 << 15, [&](int64_t begin, int64_t end) {
    if (grad == nullptr) {
      for (int64_t i = begin; i < end; ++i) {
        const float m = exp_avg[i] * beta1;
        const float v = exp_avg_sq[i] * beta2;
        exp_avg[i] = m;
        exp_avg_sq[i] = v;
        param[i] -= step_size * m / (std::sqrt(v) * inv_sqrt_bias2 + eps);
      }
      return;
    }
    for (int64_t i = begin; i < end; ++i) {
      const float g = grad[i];
      const float m = exp_avg[i] * beta1 + g * one_minus_beta1;
      const float v = exp_avg_sq[i] * beta2 + g * g * one_minus_beta2;
      exp_avg[i] = m;
      exp_avg_sq[i] = v;
      param[i] -= step_size * m / (std::sqrt(v) * inv_sqrt_bias2 + eps);
    }
  });
}

void Adam::add(const std::string& name, const torch::Tensor& param, double lr) {
  for (const auto& g : groups_)
    if (g.name == name) throw core::Error("Adam: parameter group '" + name + "' added twice");
  core::require(param.scalar_type() == torch::kFloat32 && param.is_contiguous(),
                "Adam: parameter '" + name + "' must be a contiguous float32 tensor");
  AdamGroup g;
  g.name = name;
  g.param = param;
  g.exp_avg = torch::zeros_like(param);
  g.exp_avg_sq = torch::zeros_like(param);
  g.lr = lr;
  groups_.push_back(std::move(g));
}

AdamGroup& Adam::group(const std::string& name) {
  for (auto& g : groups_)
    if (g.name == name) return g;
  throw core::Error("Adam: no parameter group '" + name + "'");
}

const AdamGroup& Adam::group(const std::string& name) const {
  return const_cast<Adam*>(this)->group(name);
}

void Adam::step() {
  step(std::vector<RowSet>{});
}

namespace {

// The rows of the first set naming the group; undefined: every row.
torch::Tensor rows_of(const std::string& group, const std::vector<Adam::RowSet>& row_sets) {
  for (const Adam::RowSet& set : row_sets)
    for (const std::string& prefix : set.prefixes)
      if (group.rfind(prefix, 0) == 0) return set.rows;
  return {};
}

}  // namespace

void Adam::step(const std::vector<RowSet>& row_sets) {
  torch::NoGradGuard no_grad;
  for (auto& g : groups_) {
    const torch::Tensor& grad_ref = g.param.grad();
    if (!grad_ref.defined() || g.param.numel() == 0) continue;
    auto grad = grad_ref.to(torch::kFloat32).contiguous();
    ++g.step;
    const torch::Tensor rows = rows_of(g.name, row_sets);
    if (!rows.defined()) {
      fused_adam_update(g.param.data_ptr<float>(), grad.data_ptr<float>(),
                        g.exp_avg.data_ptr<float>(), g.exp_avg_sq.data_ptr<float>(),
                        g.param.numel(), g.lr, g.step, options_);
      continue;
    }
    // The rows as contiguous copies, updated, then written back.
    auto param = g.param.index_select(0, rows).contiguous();
    auto exp_avg = g.exp_avg.index_select(0, rows).contiguous();
    auto exp_avg_sq = g.exp_avg_sq.index_select(0, rows).contiguous();
    auto row_grad = grad.index_select(0, rows).contiguous();
    fused_adam_update(param.data_ptr<float>(), row_grad.data_ptr<float>(),
                      exp_avg.data_ptr<float>(), exp_avg_sq.data_ptr<float>(), param.numel(), g.lr,
                      g.step, options_);
    g.param.index_copy_(0, rows, param);
    g.exp_avg.index_copy_(0, rows, exp_avg);
    g.exp_avg_sq.index_copy_(0, rows, exp_avg_sq);
  }
}

std::function<void(int64_t, int64_t, const float*)> Adam::row_step(const std::string& name) {
  AdamGroup& g = group(name);
  core::require(g.param.dim() >= 1, "Adam: row_step of '" + name + "' needs rows");
  ++g.step;
  const int64_t row = g.param.size(0) > 0 ? g.param.numel() / g.param.size(0) : 0;
  float* param = g.param.data_ptr<float>();
  float* exp_avg = g.exp_avg.data_ptr<float>();
  float* exp_avg_sq = g.exp_avg_sq.data_ptr<float>();
  const double lr = g.lr;
  const int64_t step = g.step;
  const AdamOptions options = options_;
  return [=](int64_t first, int64_t count, const float* grad) {
    const int64_t offset = first * row;
    fused_adam_update(param + offset, grad, exp_avg + offset, exp_avg_sq + offset, count * row, lr,
                      step, options);
  };
}

void Adam::coast(const std::vector<std::string>& names) {
  torch::NoGradGuard no_grad;
  for (const std::string& name : names) {
    AdamGroup& g = group(name);
    ++g.step;
    if (g.param.numel() == 0) continue;
    fused_adam_update(g.param.data_ptr<float>(), nullptr, g.exp_avg.data_ptr<float>(),
                      g.exp_avg_sq.data_ptr<float>(), g.param.numel(), g.lr, g.step, options_);
  }
}

void Adam::zero_grad() {
  for (auto& g : groups_)
    if (g.param.grad().defined()) g.param.mutable_grad() = torch::Tensor();
}

void Adam::remap_rows(const std::string& name, const torch::Tensor& new_param,
                      const torch::Tensor& index) {
  AdamGroup& g = group(name);
  core::require(new_param.size(0) == index.size(0) && new_param.is_contiguous(),
                "Adam: remap_rows of '" + name + "' with mismatched row counts");
  torch::NoGradGuard no_grad;
  auto valid = index >= 0;
  auto source = index.clamp_min(0);
  auto remap = [&](const torch::Tensor& moment) {
    if (moment.size(0) == 0) return torch::zeros_like(new_param);
    auto rows = moment.index_select(0, source);
    auto mask_shape = std::vector<int64_t>(size_t(moment.dim()), 1);
    mask_shape[0] = -1;
    return (rows * valid.to(rows.dtype()).view(mask_shape)).contiguous();
  };
  g.exp_avg = remap(g.exp_avg);
  g.exp_avg_sq = remap(g.exp_avg_sq);
  g.param = new_param;
}

void Adam::reset_moments(const std::string& name) {
  AdamGroup& g = group(name);
  g.exp_avg.zero_();
  g.exp_avg_sq.zero_();
}

void Adam::save(torch::serialize::OutputArchive& archive) const {
  for (const auto& g : groups_) {
    archive.write(g.name + ".exp_avg", g.exp_avg);
    archive.write(g.name + ".exp_avg_sq", g.exp_avg_sq);
    archive.write(g.name + ".step", c10::IValue(g.step));
    archive.write(g.name + ".lr", c10::IValue(g.lr));
  }
}

void Adam::load(torch::serialize::InputArchive& archive, const std::string& source) {
  for (auto& g : groups_) {
    torch::Tensor m, v;
    c10::IValue step, lr;
    if (!archive.try_read(g.name + ".exp_avg", m) || !archive.try_read(g.name + ".exp_avg_sq", v) ||
        !archive.try_read(g.name + ".step", step) || !archive.try_read(g.name + ".lr", lr))
      throw core::Error(source, "no optimizer state for parameter '" + g.name + "'");
    if (m.sizes() != g.param.sizes() || v.sizes() != g.param.sizes())
      throw core::Error(source, "optimizer state of '" + g.name + "' has the wrong shape");
    g.exp_avg = m.to(torch::kFloat32).contiguous();
    g.exp_avg_sq = v.to(torch::kFloat32).contiguous();
    g.step = step.toInt();
    g.lr = lr.toDouble();
  }
}

double exponential_lr(int64_t step, double lr_init, double lr_final, int64_t max_steps,
                      int64_t delay_steps, double delay_mult) {
  if (step < 0 || (lr_init == 0 && lr_final == 0)) return 0;
  double delay = 1.0;
  if (delay_steps > 0)
    delay =
        delay_mult +
        (1 - delay_mult) * std::sin(0.5 * M_PI * std::clamp(double(step) / delay_steps, 0.0, 1.0));
  const double t = max_steps > 0 ? std::clamp(double(step) / double(max_steps), 0.0, 1.0) : 1.0;
  return delay * std::exp(std::log(lr_init) * (1 - t) + std::log(lr_final) * t);
}

}  // namespace ddhgs::model
