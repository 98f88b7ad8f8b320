#include "train/trainer.h"

#include <ATen/CPUGeneratorImpl.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <optional>

#include "core/band_map.h"
#include "core/buffer_pool.h"
#include "core/error.h"
#include "core/log.h"
#include "core/stage_timer.h"
#include "core/threads.h"
#include "eval/evaluate.h"
#include "io/blocks/ground.h"
#include "model/densify.h"
#include "train/band_draw.h"
#include "train/diffusion_stage.h"
#include "train/run_checks.h"
#include "train/seed.h"
#include "train/stop_signal.h"

namespace ddhgs::train {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

bool every(int64_t iteration, int64_t interval) {
  return interval > 0 && iteration % interval == 0;
}

}  // namespace

Trainer::~Trainer() = default;

torch::Tensor Trainer::band_offsets() {
  return encoder_ ? encoder_->forward(wavelengths01_) : torch::Tensor();
}

void Trainer::set_learning_rates(int64_t iteration) {
  const OptimConfig& o = config_.optim;
  state_.adam.group("means").lr =
      extent_ * model::exponential_lr(iteration, o.means_lr_init, o.means_lr_final,
                                      schedule_.means_lr_decay_steps);
  // The other rates: constant, then log-linear down to lr_final_scale x.
  const int64_t from = schedule_.lr_decay_from;
  const double late = iteration <= from
                          ? 1.0
                          : model::exponential_lr(iteration - from, 1.0, o.lr_final_scale,
                                                  schedule_.iterations - from);
  state_.adam.group("log_scales").lr = late * o.scaling_lr;
  state_.adam.group("quats").lr = late * o.rotation_lr;
  state_.adam.group("logit_opacities").lr = late * o.opacity_lr;
  const double sh_lr =
      late * o.sh_dc_lr * state_.gaussians.colour.sh_rate_scale(o.latent_sh_lr_scale);
  state_.adam.group("sh_dc").lr = sh_lr;
  state_.adam.group("sh_rest").lr = sh_lr / o.sh_rest_lr_divisor;
  // The colour model's basis and mean, the learned background and the views'
  // gains fall with them; the other modules (encoder, cameras, denoiser) keep
  // their rates.
  for (const auto& m : state_.modules)
    if (m.name == kColourModule || m.name == kBackgroundModule || m.name == kExposureModule)
      scale_module_rate(state_.adam, m, late);
  if (camera_refinement_)
    state_.adam.group("camera_refinement/translation").lr =
        config_.camera_refinement.translation_lr;
  if (rig_refinement_) {
    // Without an alignment phase the band cameras' corrections fall with
    // the other rates, to settle within a small fraction of their rate; with
    // one they fall log-linearly to a tenth over it and are held after it.
    double scale = late;
    if (schedule_.rig_align_until > 0) {
      const int64_t start = schedule_.reference_views_until, end = schedule_.rig_align_until;
      scale =
          iteration <= start ? 1.0
          : iteration <= end
              ? std::pow(0.1, double(iteration - start) / double(std::max<int64_t>(1, end - start)))
              : 0.0;
    }
    state_.adam.group("rig_refinement/rotation").lr =
        scale * config_.camera_refinement.rig_rotation_lr;
    state_.adam.group("rig_refinement/offset").lr = scale * config_.camera_refinement.rig_offset_lr;
  }
}

render::RenderOutput Trainer::render_training_view(int view, const torch::Tensor& sink,
                                                   const render::ShRestSink& rest_step,
                                                   const torch::Tensor& band_map,
                                                   const ViewCrop* crop) {
  const core::Camera camera =
      crop ? crop_camera(scene_->views[view].camera, *crop) : scene_->views[view].camera;
  model::Gaussians g = state_.gaussians;  // handles to the same tensors
  if (band_map.defined()) g.colour = g.colour.mapped(band_map);
  if (aligning_rig_ && scene_->views[size_t(view)].rig_camera != scene_->rig->reference_camera) {
    // The alignment phase: a band camera's view moves its correction and
    // the colours, not the Gaussians' shape, which the reference camera's
    // views alone place.
    g.means = g.means.detach();
    g.quats = g.quats.detach();
    g.log_scales = g.log_scales.detach();
    g.logit_opacities = g.logit_opacities.detach();
  }
  if (rig_refinement_)
    std::tie(g.means, g.quats) = rig_refinement_->move(view, camera, g.means, g.quats, extent_);
  if (camera_refinement_)
    std::tie(g.means, g.quats) = camera_refinement_->move(view, camera, g.means, g.quats, extent_);
  return model::render_gaussians(g, camera, background_, band_offsets(), sink, rest_step);
}

torch::Tensor Trainer::render_view(int view) {
  torch::NoGradGuard no_grad;
  return render_training_view(view, {}).image;
}

torch::Tensor Trainer::render_camera(const core::Camera& camera) {
  torch::NoGradGuard no_grad;
  return model::render_gaussians(state_.gaussians, camera, background_, band_offsets()).image;
}

int Trainer::view_for(int64_t iteration) const {
  const bool warmup = !reference_train_.empty() && schedule_.reference_views_only(iteration);
  const std::vector<int>& views = warmup ? reference_train_ : scene_->train;
  const int64_t n = int64_t(views.size());
  // The block's views take the first of the flight's slots (which views
  // they are does not matter: every permutation is as likely).
  const int64_t slots = warmup ? n : schedule_views();
  const int64_t slot = epoch_slot(iteration, slots, config_.seed);
  return slot < n ? views[size_t(slot)] : kElsewhere;
}

int64_t Trainer::schedule_views() const {
  return block_ ? block_->flight_train_views : int64_t(scene_->train.size());
}

json Trainer::coast(int64_t iteration) {
  {
    core::StageScope stage("adam");
    state_.adam.coast(model::Gaussians::tensor_names());
  }
  measure_test_views(iteration);
  densify_after(iteration);
  json record = {{"iter", iteration},
                 {"elsewhere", true},
                 {"num_gaussians", state_.gaussians.size()},
                 {"densify_added", state_.counters.densify_added},
                 {"densify_removed", state_.counters.densify_removed}};
  if (!step_test_.is_null()) record.update(step_test_);
  return record;
}

void Trainer::measure_test_views(int64_t iteration) {
  // A test record measures the Gaussians this step has optimised, before
  // densification clones, splits, prunes and resets their opacity: measured
  // after, the held-out views would see a model the next steps have not yet
  // fitted again (1-6 dB low on a densifying iteration, 13-15 dB on an
  // opacity reset; the iterations between agree, docs/benchmarks.md).
  step_test_ = json();
  if (!measures_test_views(iteration)) return;
  const auto measure_start = std::chrono::steady_clock::now();
  step_test_ = test_psnr();
  test_seconds_ +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - measure_start).count();
}

void Trainer::densify_after(int64_t iteration) {
  if (!schedule_.densifies(iteration)) return;
  core::StageScope stage("densify");
  auto& g = state_.gaussians;
  const int64_t reset_every = schedule_.opacity_reset_every;
  if (iteration > schedule_.densify_from && every(iteration, schedule_.densify_every)) {
    auto generator =
        at::make_generator<at::CPUGeneratorImpl>(mix_seed(config_.seed, uint64_t(2 * iteration)));
    const int64_t before = g.size();
    auto r =
        model::densify_and_prune(g, state_.adam, state_.stats, config_.densify.thresholds, extent_,
                                 reset_every > 0 && iteration > reset_every, generator);
    state_.counters.densify_added += r.cloned + r.split;
    state_.counters.densify_removed += r.pruned;
    core::log_debug("densify at " + std::to_string(iteration) + ": " + std::to_string(before) +
                    " -> " + std::to_string(g.size()) + " (" + std::to_string(r.cloned) +
                    " cloned, " + std::to_string(r.split) + " split, " + std::to_string(r.pruned) +
                    " pruned: " + std::to_string(r.pruned_transparent) + " transparent, " +
                    std::to_string(r.pruned_screen) + " large on screen, " +
                    std::to_string(r.pruned_world) + " large in the world)");
  }
  if (every(iteration, reset_every)) model::reset_opacity(g, state_.adam);
}

torch::Tensor Trainer::block_loss_mask(const core::Camera& camera, const ViewCrop* crop,
                                       int64_t height, int64_t width) const {
  return io::ground_box_mask(block_->frame, block_->margined, camera, crop ? crop->x0 : 0,
                             crop ? crop->y0 : 0, int(width), int(height))
      .unsqueeze(-1);
}

torch::Tensor Trainer::band_map(const torch::Tensor& bands) const {
  if (!bands.defined()) return {};
  const int64_t* b = bands.data_ptr<int64_t>();
  return core::selection_map(scene_->bands(), std::vector<int64_t>(b, b + bands.numel()));
}

torch::Tensor Trainer::step_bands(int64_t iteration, int view) const {
  const int64_t count = config_.loss.bands_per_step, bands = scene_->bands();
  // Per band, a band's SH would learn only when drawn; the joint diffusion
  // term conditions on the whole render; a band-per-view camera holds its own.
  const bool joint = diffusion_ && diffusion_->options().joint;
  if (count <= 0 || count >= bands || !schedule_.draws_bands(iteration) ||
      !state_.gaussians.colour.latent() || joint || scene_->view_bands(view).defined())
    return {};
  return draw_bands(bands, count, mix_seed(config_.seed, kBandStream + uint64_t(iteration)));
}

double Trainer::view_fraction(int width, int height) const {
  // The joint diffusion term draws its own crops of the whole render.
  if (diffusion_ && diffusion_->options().joint) return 1;
  return crop_fraction(config_.loss.view_fraction, config_.loss.view_fraction_from_pixels, width,
                       height);
}

std::optional<ViewCrop> Trainer::step_crop(int64_t iteration, int width, int height) const {
  const double fraction = view_fraction(width, height);
  if (fraction >= 1 || !schedule_.crops_views(iteration)) return std::nullopt;
  const ViewCrop crop = draw_view_crop(width, height, fraction,
                                       mix_seed(config_.seed, kCropStream + uint64_t(iteration)));
  if (crop.width() == width && crop.height() == height) return std::nullopt;
  return crop;
}

json Trainer::step(int64_t iteration, const PseudoView* pseudo) {
  core::StageScope step_scope("step (other)");
  // The denoiser's convolutions are large enough for LibTorch's own threads.
  std::optional<core::TorchThreads> torch_threads;
  const bool joint = diffusion_ && diffusion_->options().joint && iteration <= config_.iterations;
  if (joint && iteration > diffusion_->options().warmup) torch_threads.emplace();
  set_learning_rates(iteration);
  aligning_rig_ = rig_refinement_ && !pseudo && schedule_.aligns_rig(iteration);
  auto& g = state_.gaussians;
  if (every(iteration, schedule_.sh_degree_every) && g.active_sh_degree < g.max_sh_degree())
    ++g.active_sh_degree;

  const int view = pseudo ? -1 : view_for(iteration);
  if (view == kElsewhere && !pseudo) return coast(iteration);
  const core::Camera& camera = pseudo ? pseudo->camera : scene_->views[view].camera;
  const torch::Tensor bands = pseudo ? torch::Tensor() : step_bands(iteration, view);
  const std::optional<ViewCrop> crop =
      pseudo ? std::nullopt
             : step_crop(iteration, camera.intrinsics.width, camera.intrinsics.height);
  // The crop's images (target, render, loss gradient) take blocks of the
  // whole view's size, whatever the crop's (core/buffer_pool.h).
  std::optional<core::CropScope> crop_blocks;
  if (crop)
    crop_blocks.emplace(int64_t(crop->width()) * crop->height(),
                        int64_t(camera.intrinsics.width) * camera.intrinsics.height);
  torch::Tensor target;
  {
    core::StageScope stage("view (to float)");
    if (pseudo) {
      target = pseudo->target;  // every band, whole view
    } else {
      // Only the crop's samples of the drawn bands are converted to float.
      io::ImageWindow window;
      if (crop) window = {crop->x0, crop->y0, crop->x1, crop->y1, {}};
      window.bands = bands;
      target = scene_->image(view, window);
    }
  }
  auto sink = torch::zeros({g.size(), 2}).requires_grad_(true);
  render::RenderOutput out;
  {
    core::StageScope stage("render (other)");
    // Adam updates the SH rest coefficients block by block inside the SH
    // backward: their [G, N, 15] gradient is never stored.
    render::ShRestSink rest_step;
    if (g.sh_rest.numel() > 0) rest_step = state_.adam.row_step("sh_rest");
    out = pseudo ? model::render_gaussians(g, camera, background_, band_offsets(), sink, rest_step)
                 : render_training_view(view, sink, rest_step, band_map(bands),
                                        crop ? &*crop : nullptr);
  }
  // A view of a band-per-view scene supervises only the bands it holds, lit
  // as its capture was (the exposure correction's gains).
  torch::Tensor rendered = pseudo ? out.image : scene_->view_slice(view, out.image);
  if (exposure_ && !pseudo)
    rendered = exposure_->apply(view, rendered, bands.defined() ? bands : scene_->view_bands(view));
  // A block learns the ground of its cell and margin: elsewhere the target
  // is the render itself, which no loss term pulls on.
  torch::Tensor inside;  // [H, W, 1] bool: a block's pixels that the loss measures
  if (block_ && !pseudo) {
    core::StageScope stage("block mask");
    inside = block_loss_mask(camera, crop ? &*crop : nullptr, rendered.size(0), rendered.size(1));
    target = torch::where(inside, target, rendered.detach());
  }
  LossValues loss;
  {
    core::StageScope stage("losses (other)");
    // After the Gaussian iterations (distillation) the joint term is over.
    std::vector<LossTerm> after;
    if (iteration > config_.iterations)
      for (const LossTerm& term : losses_)
        if (term.name != "diffusion") after.push_back(term);
    loss = evaluate_losses(iteration > config_.iterations ? after : losses_,
                           {rendered, target, view, iteration,
                            mix_seed(config_.seed, kTermStream + uint64_t(iteration))});
    if (pseudo) loss.total = loss.total * diffusion_->options().distill_weight;
    if (crop) loss.total = loss.total * crop->loss_scale;
    if (rig_refinement_ && !pseudo)
      loss.total = loss.total + rig_refinement_->pull(config_.camera_refinement.rig_pull, extent_);
  }
  {
    core::StageScope stage("backward (other)");
    loss.total.backward();
  }
  crop_blocks.reset();

  if (schedule_.densifies(iteration) && sink.grad().defined()) {
    core::StageScope stage("densify stats");
    state_.stats.accumulate(out.radii, crop ? sink.grad() * crop->coverage : sink.grad(),
                            camera.intrinsics.width, camera.intrinsics.height);
  }
  {
    core::StageScope stage("adam");
    // Parameters with one row per band learn on the bands measured, the
    // views' gains on the view measured.
    std::vector<model::Adam::RowSet> rows;
    if (bands.defined())
      rows.push_back(
          {{kBackgroundModule + std::string("/"), kColourModule + std::string("/")}, bands});
    if (exposure_ && !pseudo)
      rows.push_back({{kExposureModule + std::string("/")}, torch::tensor({int64_t(view)})});
    state_.adam.step(rows);
    state_.adam.zero_grad();
    if (camera_refinement_) camera_refinement_->recentre();
    if (exposure_) exposure_->recentre();
  }

  if (pseudo)
    step_test_ = json();
  else
    measure_test_views(iteration);
  densify_after(iteration);

  core::StageScope stage("metrics");
  json record = {{"iter", iteration}, {"loss", loss.total.item<double>()}};
  for (const auto& [name, value] : loss.terms) record[name] = value;
  if (keeps_record(iteration)) {
    if (!inside.defined()) {
      record["train_psnr"] = psnr(rendered, target);
    } else if (inside.any().item<bool>()) {
      // Over the pixels the block learns: elsewhere the target is the
      // render itself, which would flatter the figure (120 dB on a view
      // that sees none of the block's ground).
      const torch::Tensor measured = inside.expand_as(rendered);
      record["train_psnr"] =
          psnr(rendered.detach().masked_select(measured), target.masked_select(measured));
    }
  }
  record["num_gaussians"] = g.size();
  record["densify_added"] = state_.counters.densify_added;
  record["densify_removed"] = state_.counters.densify_removed;
  if (!step_test_.is_null()) record.update(step_test_);
  return record;
}

bool Trainer::measures_test_views(int64_t iteration) const {
  // The auxiliary models of the diffusion pairs keep no records.
  return !auxiliary_ && iteration <= config_.iterations &&
         every(iteration, config_.output.test_every);
}

bool Trainer::keeps_record(int64_t iteration) const {
  // The first and last of the run and the first of the fine-tuning.
  return measures_test_views(iteration) || every(iteration, config_.output.log_every) ||
         iteration == total_steps() || iteration == 1 || iteration == config_.iterations + 1;
}

json Trainer::advance() {
  const int64_t iteration = state_.iteration + 1;
  json record = step(iteration, nullptr);
  state_.iteration = iteration;
  return record;
}

int64_t Trainer::finetune_end() const {
  return stage_ ? stage_->finetune_end() : config_.iterations;
}

int64_t Trainer::total_steps() const {
  return stage_ ? stage_->total_steps() : config_.iterations;
}

json Trainer::test_psnr() {
  // A quick held-out check: PSNR as `ddhgs eval` measures it (the clamped
  // render, per view, then the mean over views), without eval's SSIM, SAM and
  // per-band figures, which cost minutes per view at 640x512x141.
  json out = json::object();  // summary.update() needs an object, even empty
  if (scene_->test.empty()) return out;
  torch::NoGradGuard no_grad;
  const torch::Tensor offsets = band_offsets();
  double stored = 0, clean = 0;
  size_t cleans = 0;
  for (int v : scene_->test) {
    // A rig's held-out views are seen by their corrected band cameras.
    const core::Camera camera =
        rig_refinement_ ? rig_refinement_->corrected(v, scene_->views[v].camera, extent_)
                        : scene_->views[v].camera;
    const torch::Tensor image = scene_->view_slice(
        v,
        model::render_gaussians(state_.gaussians, camera, background_, offsets).image.clamp(0, 1));
    stored += eval::psnr_db(image, scene_->image(v));
    const torch::Tensor truth = scene_->clean_image(v);
    if (truth.defined()) {
      clean += eval::psnr_db(image, truth);
      ++cleans;
    }
  }
  out["test_psnr"] = stored / double(scene_->test.size());
  if (cleans > 0) out["test_psnr_clean"] = clean / double(cleans);
  return out;
}

TrainStatus Trainer::run() {
  TrainStatus status;
  try {
    status = run_steps();
  } catch (...) {
    writer_->failed();
    throw;
  }
  if (status == TrainStatus::Finished) writer_->finished();
  return status;
}

TrainStatus Trainer::run_steps() {
  const int64_t iterations = config_.iterations;
  const int64_t total = total_steps();
  const int64_t checkpoint_every = config_.output.checkpoint_every;
  MetricsLog metrics(run_.metrics(), state_.iteration);
  StopSignalGuard guard;
  const double seconds_before = state_.counters.seconds;
  const auto start = std::chrono::steady_clock::now();
  test_seconds_ = 0;  // seconds spent on test-view records, not training
  json test_at_end;   // the record's test PSNR at the last Gaussian iteration, if taken
  auto elapsed = [&] {
    return seconds_before - test_seconds_ +
           std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  core::ProgressBar bar("train", total);
  bar.update(state_.iteration);

  // Runs one phase up to iteration `end` (the iteration counter runs on
  // through both): each step's record is checked, logged and shown, and
  // checkpoints are kept. False when a stop signal interrupted it.
  using StepFn = std::function<json(int64_t)>;
  using StatusFn = std::function<std::string(const json&)>;
  auto run_phase = [&](int64_t end, const StepFn& step_of, const StatusFn& status_of) {
    while (state_.iteration < end) {
      if (stop_requested()) return false;
      const int64_t iteration = state_.iteration + 1;
      json record = step_of(iteration);
      require_finite_record(record, run_.root);
      state_.iteration = iteration;
      // The Gaussians' share of the time, for seconds per iteration.
      if (iteration == iterations) state_.counters.gaussian_seconds = elapsed();
      // Test-view PSNR against training time (the report's time-to-quality
      // curve), taken inside the step (before densification); rendering the
      // test views changes no state, so resume stays bit for bit.
      if (iteration == iterations) test_at_end = step_test_;
      if (keeps_record(iteration)) {
        record["seconds"] = elapsed();
        metrics.write(record);
      }
      bar.update(iteration, status_of(record));
      // The end of the Gaussian iterations is always kept when the
      // fine-tuning follows: resuming with more iterations starts there.
      if ((every(iteration, checkpoint_every) || iteration == iterations) && iteration < total) {
        state_.counters.seconds = elapsed();
        save(true);
      }
    }
    return true;
  };
  // The training-view PSNR of the last record that measured it (keeps_record),
  // and the loss of the last step that rendered a view (a block's steps
  // elsewhere in its flight have none).
  double shown_psnr = std::nan(""), shown_loss = std::nan("");
  auto gaussian_status = [&shown_psnr, &shown_loss](const json& record) {
    if (record.contains("train_psnr")) shown_psnr = record["train_psnr"].get<double>();
    if (record.contains("loss")) shown_loss = record["loss"].get<double>();
    // A block whose first steps lie elsewhere has no loss to show yet.
    char loss_text[40] = "", psnr_text[40] = "";
    if (!std::isnan(shown_loss))
      std::snprintf(loss_text, sizeof loss_text, "loss %.4f  ", shown_loss);
    if (!std::isnan(shown_psnr))
      std::snprintf(psnr_text, sizeof psnr_text, "psnr %.2f dB  ", shown_psnr);
    char text[160];
    std::snprintf(text, sizeof text, "%s%sG %lld", loss_text, psnr_text,
                  (long long)record["num_gaussians"].get<int64_t>());
    return std::string(text);
  };
  auto finetune_status = [](const json& record) {
    char text[160];
    std::snprintf(text, sizeof text, "denoiser fine-tuning  loss %.4f (render as is %.4f)",
                  record["diffusion_avg"].get<double>(),
                  record["diffusion_identity_avg"].get<double>());
    return std::string(text);
  };
  const bool finished =
      run_phase(
          iterations, [this](int64_t i) { return step(i, nullptr); }, gaussian_status) &&
      run_phase(
          finetune_end(), [this](int64_t i) { return stage_->finetune_step(i); },
          finetune_status) &&
      run_phase(
          total, [this](int64_t i) { return stage_->distill_step(i); }, gaussian_status);
  state_.counters.seconds = elapsed();
  if (!finished) {
    save(false);
    bar.finish("interrupted");
    core::log_info("interrupted at iteration " + std::to_string(state_.iteration) +
                   "; checkpoint saved. Continue with: ddhgs train --resume " + run_.root.string());
    return TrainStatus::Interrupted;
  }
  // The step's reusable buffers (SH gradients, images: about 1.3 GB at 100k
  // Gaussians, 141 bands, 640x512) are not needed by the outputs below.
  core::pool_release_idle();
  save(true);
  if (total > finetune_end()) {
    // The distillation changed the Gaussians: measure them again, and keep
    // what they scored before it.
    json before = json::object();
    for (const auto& [key, value] : test_at_end.items())
      before[key + "_before_distillation"] = value;
    test_at_end = test_psnr();
    test_at_end.update(before);
  }
  write_outputs(state_.counters.seconds, test_at_end);
  fs::remove(run_.pseudo_views());
  bar.finish();
  return TrainStatus::Finished;
}

}  // namespace ddhgs::train
