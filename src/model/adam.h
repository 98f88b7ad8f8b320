// Adam with a fused in-place step, and the learning-rate schedules of 3DGS.
//
// One pass per parameter reads the gradient and updates the parameter and both
// moments in place, in parallel, so the SH tensors ([G, N, 15] floats, the bulk
// of the model) are not copied by chains of tensor ops. Parameters are grouped
// by name; groups that hold one row per Gaussian follow densification through
// select_rows / append_rows, which move their moments with the rows.
#pragma once
#include <torch/serialize/archive.h>

#include <functional>
#include <string>
#include <vector>

#include "core/tensor.h"

namespace ddhgs::model {

struct AdamOptions {
  double beta1 = 0.9;
  double beta2 = 0.999;
  double eps = 1e-15;
};

struct AdamGroup {
  std::string name;
  torch::Tensor param;       // float32, contiguous, requires_grad; shares storage with the model
  torch::Tensor exp_avg;     // same shape as param
  torch::Tensor exp_avg_sq;  // same shape as param
  double lr = 0;
  int64_t step = 0;
};

class Adam {
 public:
  explicit Adam(AdamOptions options = {}) : options_(options) {}

  // Registers a parameter under a unique name with zero moments.
  void add(const std::string& name, const torch::Tensor& param, double lr);
  AdamGroup& group(const std::string& name);
  const AdamGroup& group(const std::string& name) const;
  std::vector<AdamGroup>& groups() { return groups_; }
  const AdamOptions& options() const { return options_; }

  // Updates every group whose parameter has a gradient, then leaves the
  // gradients as they are (call zero_grad before the next backward).
  void step();
  // Some rows of the groups whose names start with one of `prefixes`:
  // [R] int64 indices along dim 0 (undefined: all rows).
  struct RowSet {
    std::vector<std::string> prefixes;
    torch::Tensor rows;
  };
  // As step(), but a group named by a row set (the first that names it)
  // updates only that set's rows: the others keep their values and both
  // moments, as if the step had not happened for them. For parameters with
  // one row per band when a step measured some bands (train/band_draw.h), or
  // one row per view when it measured one view: plain Adam would move the
  // others on momentum alone. Bias correction uses the group's step count.
  void step(const std::vector<RowSet>& row_sets);
  // A step with zero gradients for the groups named (every row): each
  // moves on its first moment alone and both moments decay, as the
  // parameters of plain Adam do on a step whose loss does not reach them.
  // The groups' gradients are neither read nor changed.
  void coast(const std::vector<std::string>& names);
  void zero_grad();

  // For a group whose gradient arrives in blocks of rows during the backward
  // (render::eval_sh's rest sink) instead of in .grad(): counts this step and
  // returns the update of rows [first, first + count) from their gradient
  // [count, ...], the same arithmetic as step(). Every row once per step, in
  // any order, from any thread. Valid until the group's tensors are replaced
  // (densification); step() then skips the group, whose .grad() is undefined.
  std::function<void(int64_t first, int64_t count, const float* grad)> row_step(
      const std::string& name);

  // Replaces a group's parameter by new_param and its moments by rows of the
  // old moments: new row i takes old row index[i], or zeros where index[i] < 0.
  // index: [G'] int64. new_param must already have G' rows.
  void remap_rows(const std::string& name, const torch::Tensor& new_param,
                  const torch::Tensor& index);
  // Zeroes one group's moments (after a parameter reset, e.g. opacities).
  void reset_moments(const std::string& name);

  // Moments, steps and learning rates, keyed "<group>.<field>".
  void save(torch::serialize::OutputArchive& archive) const;
  // Restores state for groups already registered (same names and shapes as
  // saved); throws core::Error naming `source` on a mismatch.
  void load(torch::serialize::InputArchive& archive, const std::string& source);

 private:
  AdamOptions options_;
  std::vector<AdamGroup> groups_;
};

// The fused update on raw float32 arrays of length n, exposed for tests and
// benchmarks. step is the 1-based step count after this update.
// grad null: a zero gradient (Adam::coast).
void fused_adam_update(float* param, const float* grad, float* exp_avg, float* exp_avg_sq,
                       int64_t n, double lr, int64_t step, const AdamOptions& options);

// 3DGS's position schedule: log-linear from lr_init to lr_final over
// max_steps, with an optional sine-shaped warm-up (delay_mult < 1 over
// delay_steps). Constant lr_final after max_steps.
double exponential_lr(int64_t step, double lr_init, double lr_final, int64_t max_steps,
                      int64_t delay_steps = 0, double delay_mult = 1.0);

}  // namespace ddhgs::model
