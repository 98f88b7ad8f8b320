#include "train/trainer.h"

#include <ATen/CPUGeneratorImpl.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
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
#include "io/files/atomic_file.h"
#include "io/ply/ply.h"
#include "io/scene/backdrop.h"
#include "model/densify.h"
#include "train/band_draw.h"
#include "train/config.h"
#include "train/init.h"
#include "train/model_shape.h"
#include "train/novel_views.h"
#include "train/run_checks.h"

namespace ddhgs::train {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::atomic<bool> g_stop{false};
std::atomic<int> g_stop_signal{0};

extern "C" void on_stop_signal(int signal) {
  g_stop_signal = signal;
  g_stop = true;
}

// Ctrl-C and the SIGTERM of batch schedulers and `systemctl stop` both save a
// checkpoint; the previous handlers come back when training ends.
class StopSignalGuard {
 public:
  StopSignalGuard() {
    previous_int_ = std::signal(SIGINT, on_stop_signal);
    previous_term_ = std::signal(SIGTERM, on_stop_signal);
  }
  ~StopSignalGuard() {
    std::signal(SIGINT, previous_int_);
    std::signal(SIGTERM, previous_term_);
  }

 private:
  void (*previous_int_)(int);
  void (*previous_term_)(int);
};

// Stream ids: 0 initialisation, 2 e + 1 the view order of epoch e, 2 i the
// densification of iteration i, kTermStream + i the loss terms of iteration i.
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

// The trained modules with one row per band (Adam groups "<module>/<name>").
constexpr const char* kColourModule = "colour_model";
constexpr const char* kBackgroundModule = "background";
// ... and one row per view.
constexpr const char* kExposureModule = "exposure";

bool every(int64_t iteration, int64_t interval) {
  return interval > 0 && iteration % interval == 0;
}

}  // namespace

void Trainer::request_stop() {
  g_stop = true;
}

int Trainer::stop_signal() {
  return g_stop_signal;
}

Trainer::Trainer(RunConfig config, RunPaths run)
    : config_(std::move(config)), run_(std::move(run)), schedule_(schedule_of(config_)) {}

void Trainer::load_scene() {
  const fs::path& data = config_.data.path;
  core::require(!data.empty(), run_.config(), "data.path is empty: no dataset to train on");
  scene_ = io::load_scene(data, config_.data.load);
  if (!auxiliary_) {
    io::log_scene_messages(*scene_);
  } else {  // an auxiliary model of pair_renders(): the main run said it all
    if (!held_out_.empty()) {
      std::vector<int> train;
      for (int v : scene_->train)
        if (std::find(held_out_.begin(), held_out_.end(), v) == held_out_.end()) train.push_back(v);
      scene_->train = train;
      scene_->test = held_out_;
    }
    if (perturb_px_ > 0)
      for (int v : scene_->train) {
        // perturb_px_ pixels at the image centre, whatever the lens.
        core::Camera& camera = scene_->views[size_t(v)].camera;
        const double degrees = std::atan(perturb_px_ / camera.intrinsics.fx) * 180 / M_PI;
        camera = turned(camera, degrees, mix_seed(config_.seed, kFoldStream + uint64_t(v)));
      }
  }
  core::require(!scene_->train.empty(), data, "the dataset has no training views");
  check_scene_before_training(*scene_);
  background_ = background(config_.model, scene_->bands());
  // A resumed run's learned background comes from its checkpoint.
  if (config_.model.background_from_views && !(resuming_ && config_.model.learn_background)) {
    // Only a masked capture's backdrop: a field's or a room's border is
    // scenery, which the Gaussians draw.
    const io::BorderScan border = io::scan_border(*scene_, scene_->train);
    if (border.masked) {
      background_ = border.colour;
      core::log_info("background starts from the training views' backdrop (" +
                     io::describe_colour(background_) + ")");
    } else {
      core::log_info(
          "background starts from model.background: the views show no uniform "
          "backdrop (" +
          border.why_not + ")");
    }
  }
  extent_ = scene_extent(*scene_, scene_->train);
  const LossConfig& loss = config_.loss;
  losses_ = baseline_losses(loss.l1, loss.dssim);
  losses_.push_back(spectral_term(loss.spectral, loss.spectral_options));
}

void Trainer::build_modules() {
  colour_ = resuming_ ? resumed_colour_model(*scene_, resumed_rank_)
                      : initial_colour_model(*scene_, config_.model.spectral_rank,
                                             config_.model.subspace_from_bands);
  if (colour_.latent()) {
    colour_module_ = std::make_shared<torch::nn::Module>();
    colour_.basis = colour_module_->register_parameter("basis", colour_.basis.clone());
    colour_.mean = colour_module_->register_parameter("mean", colour_.mean.clone());
    add_module(kColourModule, colour_module_, config_.optim.basis_lr);
  }
  const WavelengthEncoderConfig& we = config_.wavelength_encoder;
  if (we.enabled) {
    // Its initial weights come from the run's seed (the last layer is zero).
    torch::manual_seed(mix_seed(config_.seed, kEncoderInitStream));
    model::WavelengthEncoderOptions network = we.network;
    network.sh_coeffs = int(colour_.encoder_width(network.sh_coeffs));
    encoder_ = model::WavelengthEncoder(network);
    wavelengths01_ = model::normalise_wavelengths(scene_->wavelengths_nm);
    add_module("wavelength_encoder", encoder_.ptr(), we.lr);
  }
  if (config_.model.learn_background) {
    // A constant backdrop is otherwise drawn by Gaussians wherever the
    // training views leave room, e.g. right in front of a held-out camera.
    background_module_ = std::make_shared<torch::nn::Module>();
    background_ = background_module_->register_parameter("value", background_.clone());
    add_module(kBackgroundModule, background_module_, config_.optim.background_lr);
  }
  if (config_.camera_refinement.enabled) {
    camera_refinement_ = CameraRefinement(int64_t(scene_->views.size()), scene_->train);
    add_module("camera_refinement", camera_refinement_.ptr(),
               config_.camera_refinement.rotation_lr);
  }
  const ExposureMode exposure = config_.model.exposure_correction;
  if (exposure == ExposureMode::On || (exposure == ExposureMode::Auto && scene_->band_per_view())) {
    exposure_ = ExposureCorrection(trained_entries(*scene_));
    if (!auxiliary_)
      core::log_info(std::string("exposure correction: each training view learns a gain per band "
                                 "for its capture's light (model.exposure_correction ") +
                     (exposure == ExposureMode::On ? "on" : "auto: a band-per-view scene") +
                     "); held-out views, renders and exports are not corrected");
    add_module(kExposureModule, exposure_.ptr(), config_.optim.exposure_lr);
    losses_.push_back({"exposure_prior", config_.loss.exposure_prior, [this](const LossInputs& in) {
                         return in.view < 0 ? torch::zeros({}) : exposure_->prior(in.view);
                       }});
  }
  if (config_.camera_refinement.rig) {
    rig_refinement_ = RigRefinement(*scene_);
    add_module("rig_refinement", rig_refinement_.ptr(), config_.camera_refinement.rig_rotation_lr);
  }
  const DiffusionTermOptions diffusion = with_bands(config_.diffusion, scene_->bands());
  if (diffusion.enabled()) {
    // The denoiser sees every band of a view at once; a view that holds one
    // band has no such image.
    if (scene_->band_per_view())
      throw core::Error(scene_->root,
                        "is a band-per-view scene (each view holds some of the bands); the "
                        "diffusion stage needs every band of a view: train it with "
                        "loss.diffusion=0");
    diffusion_ =
        std::make_unique<DiffusionTerm>(diffusion, mix_seed(config_.seed, kDenoiserInitStream));
    add_module("denoiser", diffusion_->denoiser().unet.ptr(), diffusion.lr);
    if (diffusion.joint) losses_.push_back(diffusion_->loss_term());
  }
}

void Trainer::add_module(const std::string& name, std::shared_ptr<torch::nn::Module> module,
                         double lr) {
  for (const auto& m : state_.modules)
    if (m.name == name) throw core::Error("trainer: module '" + name + "' added twice");
  state_.modules.push_back({name, std::move(module), lr});
}

void Trainer::attach_colour() {
  // The module's parameters are loaded in place, so these are still its own.
  state_.gaussians.colour = colour_;
}

torch::Tensor Trainer::band_offsets() {
  return encoder_ ? encoder_->forward(wavelengths01_) : torch::Tensor();
}

void Trainer::create_optimizer() {
  model::AdamOptions options;
  options.eps = config_.optim.adam_eps;
  state_.adam = model::Adam(options);
  auto tensors = state_.gaussians.tensors();
  for (size_t i = 0; i < tensors.size(); ++i)
    state_.adam.add(model::Gaussians::tensor_names()[i], *tensors[i], 0.0);
  for (const auto& m : state_.modules) add_module_groups(state_.adam, m);
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
  if (rig_refinement_)
    state_.adam.group("rig_refinement/offset").lr = config_.camera_refinement.rig_offset_lr;
}

render::RenderOutput Trainer::render_training_view(int view, const torch::Tensor& sink,
                                                   const render::ShRestSink& rest_step,
                                                   const torch::Tensor& band_map,
                                                   const ViewCrop* crop) {
  const core::Camera camera =
      crop ? crop_camera(scene_->views[view].camera, *crop) : scene_->views[view].camera;
  model::Gaussians g = state_.gaussians;  // handles to the same tensors
  if (band_map.defined()) g.colour = g.colour.mapped(band_map);
  if (rig_refinement_)
    std::tie(g.means, g.quats) = rig_refinement_->move(view, camera, g.means, g.quats, extent_);
  if (camera_refinement_)
    std::tie(g.means, g.quats) = camera_refinement_->move(view, camera, g.means, g.quats, extent_);
  return model::render_gaussians(g, camera, background_, band_offsets(), sink, rest_step);
}

std::unique_ptr<Trainer> Trainer::start(const json& config, const RunPaths& run, bool replace) {
  RunConfig parsed = parse_run_config(config, "config");
  const std::vector<fs::path> inputs = {parsed.data.path};
  RunWriter::check(run, replace, inputs);  // before the work of loading
  std::unique_ptr<Trainer> t(new Trainer(std::move(parsed), run));
  t->load_scene();  // before touching the output, so bad input leaves it intact
  t->build_modules();
  t->initialise();
  // Every file the run will read, resolved before anything is moved: a cube
  // inside the folder being replaced would go with it.
  std::vector<fs::path> read = inputs;
  for (const io::View& v : t->scene_->views) {
    read.push_back(v.data_path);
    if (!v.clean_path.empty()) read.push_back(v.clean_path);
  }
  t->writer_ = RunWriter::create(run, config, replace, read);
  core::log_info("training " + std::to_string(t->state_.gaussians.size()) + " Gaussians x " +
                 std::to_string(t->scene_->bands()) + " bands on " +
                 std::to_string(t->scene_->train.size()) + " views (" +
                 std::to_string(t->scene_->test.size()) + " held out)");
  t->log_crops();
  return t;
}

void Trainer::log_crops() const {
  if (scene_->train.empty()) return;
  const core::Intrinsics& in = scene_->views[size_t(scene_->train.front())].camera.intrinsics;
  const double fraction = view_fraction(in.width, in.height);
  if (fraction >= 1 || !schedule_.crops_views(1)) return;
  char text[256];
  std::snprintf(text, sizeof text,
                "each step measures a random crop of about %.0f %% of its %dx%d view "
                "(loss.view_fraction %g, on views of %lld pixels or more; 1: whole views)",
                100 * fraction, in.width, in.height, config_.loss.view_fraction,
                static_cast<long long>(config_.loss.view_fraction_from_pixels));
  core::log_info(text);
}

void Trainer::initialise() {
  InitOptions options = config_.init;
  options.seed = mix_seed(config_.seed, 0);
  state_.gaussians = initialise_gaussians(*scene_, options, colour_);
  state_.stats.reset(state_.gaussians.size());
  create_optimizer();
}

std::unique_ptr<Trainer> Trainer::resume(const RunPaths& run, int64_t iterations) {
  std::unique_ptr<RunWriter> writer = RunWriter::reopen(run);
  if (!fs::exists(run.checkpoint()))
    throw core::Error(run.root,
                      "has no checkpoint to resume from (training stopped before "
                      "its first one); start it again with --force");
  json config = read_run_config(run);
  const int64_t trained = config.at("iterations").get<int64_t>();
  if (iterations > 0) config["iterations"] = iterations;
  std::unique_ptr<Trainer> t(new Trainer(parse_run_config(config, run.config().string()), run));
  t->writer_ = std::move(writer);
  t->resuming_ = true;
  t->load_scene();
  // Before anything is built or logged: the config must build the model the
  // checkpoint holds.
  CheckpointFile checkpoint = open_checkpoint(run.checkpoint());
  const SavedModel saved = saved_model(checkpoint);
  check_resumable(saved, t->config_, *t->scene_, run.checkpoint(), run.config());
  t->resumed_rank_ = saved.rank;
  t->build_modules();
  model::AdamOptions options;
  options.eps = t->config_.optim.adam_eps;
  load_checkpoint(checkpoint, t->state_, options);
  t->attach_colour();
  if (iterations > 0 && t->state_.iteration > trained) {
    // Past the Gaussian iterations (the denoiser was being fine-tuned): go
    // back to their end; the fine-tuning runs again after the new total.
    rewind_to_gaussian_end(run, trained, config);
    core::log_info("continuing from the end of the Gaussian iterations (" +
                   run.checkpoint_at(trained).string() +
                   "); the denoiser is fine-tuned again afterwards");
    auto modules = t->state_.modules;
    t->state_ = TrainState();
    t->state_.modules = modules;
    CheckpointFile end = open_checkpoint(run.checkpoint());
    check_resumable(saved_model(end), t->config_, *t->scene_, run.checkpoint(), run.config());
    load_checkpoint(end, t->state_, options);
    t->attach_colour();
  } else if (iterations > 0) {
    t->writer_->resumed(t->state_.iteration, io::read_file(run.config()));
    io::write_file_atomically(run.config(), config.dump(2) + "\n");
  }
  if (t->writer_) t->writer_->saved(t->state_.iteration);  // resumed() may have said so already
  core::log_info("resuming " + run.root.string() + " at iteration " +
                 std::to_string(t->state_.iteration));
  return t;
}

int Trainer::view_for(int64_t iteration) const {
  // A fresh permutation of the training views every epoch, seeded by epoch.
  const int64_t n = int64_t(scene_->train.size());
  const int64_t epoch = (iteration - 1) / n, position = (iteration - 1) % n;
  auto generator =
      at::make_generator<at::CPUGeneratorImpl>(mix_seed(config_.seed, uint64_t(2 * epoch + 1)));
  auto order = torch::randperm(n, generator, torch::kInt64);
  return scene_->train[size_t(order[position].item<int64_t>())];
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
  auto& g = state_.gaussians;
  if (every(iteration, schedule_.sh_degree_every) && g.active_sh_degree < g.max_sh_degree())
    ++g.active_sh_degree;

  const int view = pseudo ? -1 : view_for(iteration);
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
      loss.total = loss.total + rig_refinement_->pull(config_.camera_refinement.rig_pull);
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

  // A test record measures the Gaussians this step has optimised, before
  // densification clones, splits, prunes and resets their opacity: measured
  // after, the held-out views would see a model the next steps have not yet
  // fitted again (1-6 dB low on a densifying iteration, 13-15 dB on an
  // opacity reset; the iterations between agree, docs/benchmarks.md).
  step_test_ = json();
  if (!pseudo && measures_test_views(iteration)) {
    const auto measure_start = std::chrono::steady_clock::now();
    step_test_ = test_psnr();
    test_seconds_ +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - measure_start).count();
  }

  if (schedule_.densifies(iteration)) {
    core::StageScope stage("densify");
    const int64_t reset_every = schedule_.opacity_reset_every;
    if (iteration > schedule_.densify_from && every(iteration, schedule_.densify_every)) {
      auto generator =
          at::make_generator<at::CPUGeneratorImpl>(mix_seed(config_.seed, uint64_t(2 * iteration)));
      const int64_t before = g.size();
      auto r =
          model::densify_and_prune(g, state_.adam, state_.stats, config_.densify.thresholds,
                                   extent_, reset_every > 0 && iteration > reset_every, generator);
      state_.counters.densify_added += r.cloned + r.split;
      state_.counters.densify_removed += r.pruned;
      core::log_debug("densify at " + std::to_string(iteration) + ": " + std::to_string(before) +
                      " -> " + std::to_string(g.size()) + " (" + std::to_string(r.cloned) +
                      " cloned, " + std::to_string(r.split) + " split, " +
                      std::to_string(r.pruned) +
                      " pruned: " + std::to_string(r.pruned_transparent) + " transparent, " +
                      std::to_string(r.pruned_screen) + " large on screen, " +
                      std::to_string(r.pruned_world) + " large in the world)");
    }
    if (every(iteration, reset_every)) model::reset_opacity(g, state_.adam);
  }

  core::StageScope stage("metrics");
  json record = {{"iter", iteration}, {"loss", loss.total.item<double>()}};
  for (const auto& [name, value] : loss.terms) record[name] = value;
  if (keeps_record(iteration)) record["train_psnr"] = psnr(rendered, target);
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
  json record = step(iteration);
  state_.iteration = iteration;
  return record;
}

int64_t Trainer::finetune_end() const {
  return config_.iterations + (diffusion_ ? diffusion_->options().finetune_steps : 0);
}

int64_t Trainer::total_steps() const {
  return finetune_end() + (diffusion_ ? diffusion_->options().distill_steps : 0);
}

json Trainer::finetune_step(int64_t iteration) {
  core::TorchThreads torch_threads;  // the denoiser's convolutions
  if (!finetuning_) finetune_step_setup();
  json record = finetuning_->step(iteration - config_.iterations - 1, state_.adam,
                                  mix_seed(config_.seed, kTermStream + uint64_t(iteration)));
  record["iter"] = iteration;
  if (iteration == finetune_end()) validate_denoiser();
  return record;
}

void Trainer::finetune_step_setup() {
  if (diffusion_->options().pairs != FinetunePairs::Training && pair_renders_.empty())
    pair_renders_ = pair_renders();
  std::vector<int> views;
  validation_views_.clear();
  const int64_t every = diffusion_->options().validation_every;
  for (size_t i = 0; i < scene_->train.size(); ++i)
    (every > 0 && int64_t(i) % every == every / 2 ? validation_views_ : views)
        .push_back(scene_->train[i]);
  if (views.empty()) std::swap(views, validation_views_);
  {
    // How much error the pairs carry: their renders against the captures.
    core::TorchThreads torch_threads;
    torch::NoGradGuard no_grad;
    double sum = 0;
    for (int v : views) sum += eval::psnr_db(denoiser_condition(v).clamp(0, 1), scene_->image(v));
    denoiser_pairs_psnr_ = sum / double(views.size());
    char text[160];
    std::snprintf(text, sizeof text,
                  "denoiser pairs (%s): %zu renders at %.2f dB against their captures",
                  to_string(diffusion_->options().pairs).c_str(), views.size(),
                  denoiser_pairs_psnr_.get<double>());
    core::log_info(text);
  }
  finetuning_ = std::make_unique<DenoiserFinetuning>(
      *diffusion_, *scene_, [this](int v) { return denoiser_condition(v); }, views);
}

torch::Tensor Trainer::denoiser_condition(int view) {
  if (diffusion_->options().pairs != FinetunePairs::Training) {
    if (pair_renders_.empty()) pair_renders_ = pair_renders();
    return pair_renders_.at(view);
  }
  torch::NoGradGuard no_grad;
  return render_training_view(view, {}).image;
}

void Trainer::validate_denoiser() {
  denoiser_validation_ = {{"views", validation_views_.size()}};
  if (validation_views_.empty()) return;
  core::TorchThreads torch_threads;
  torch::NoGradGuard no_grad;
  double raw = 0, denoised = 0;
  for (size_t i = 0; i < validation_views_.size(); ++i) {
    const int v = validation_views_[i];
    const torch::Tensor render = denoiser_condition(v), target = scene_->image(v);
    model::SamplerOptions sampler = diffusion_->options().sampler;
    sampler.seed = mix_seed(config_.seed, kTermStream + uint64_t(finetune_end()) + i);
    raw += eval::psnr_db(render.clamp(0, 1), target);
    denoised += eval::psnr_db(model::denoise_view(diffusion_->denoiser(), render, sampler), target);
  }
  const double n = double(validation_views_.size());
  denoiser_validation_["psnr_render"] = raw / n;
  denoiser_validation_["psnr_denoised"] = denoised / n;
  char text[200];
  std::snprintf(text, sizeof text,
                "denoiser on %zu training views it did not learn from: %.2f dB denoised against "
                "%.2f dB as rendered (%+.2f dB)",
                validation_views_.size(), denoised / n, raw / n, (denoised - raw) / n);
  core::log_info(text);
}

std::map<int, torch::Tensor> Trainer::pair_renders() {
  const DiffusionTermOptions& o = diffusion_->options();
  // Who renders what: folds, one model per fold rendering the fold it left
  // out; checkpoint and perturbed, one model rendering every training view.
  const std::vector<std::vector<int>> groups = o.pairs == FinetunePairs::Folds
                                                   ? interleaved_folds(scene_->train, int(o.folds))
                                                   : std::vector<std::vector<int>>{scene_->train};
  RunConfig aux = config_;
  const int64_t steps =
      std::max<int64_t>(1, std::llround(o.fold_iterations * double(config_.iterations)));
  // An earlier checkpoint keeps the run's schedule and seed and stops early.
  if (o.pairs != FinetunePairs::Checkpoint) aux.iterations = steps;
  aux.diffusion.weight = 0;  // an auxiliary model has no denoiser of its own
  std::map<int, torch::Tensor> renders;
  const auto start = std::chrono::steady_clock::now();
  for (size_t f = 0; f < groups.size(); ++f) {
    if (o.pairs != FinetunePairs::Checkpoint) aux.seed = mix_seed(config_.seed, kFoldStream + f);
    std::unique_ptr<Trainer> t(new Trainer(aux, run_));
    t->auxiliary_ = true;
    if (o.pairs == FinetunePairs::Folds) t->held_out_ = groups[f];
    if (o.pairs == FinetunePairs::Perturbed) t->perturb_px_ = o.perturb_px;
    {
      // The main run has said what loading and initialising say.
      const core::LogLevel level = core::log_level();
      core::set_log_level(std::min(level, core::LogLevel::Quiet));
      struct Restore {
        core::LogLevel level;
        ~Restore() { core::set_log_level(level); }
      } restore{level};
      t->load_scene();
      t->build_modules();
      t->initialise();
    }
    const int64_t n = std::min(steps, aux.iterations);
    const std::string label =
        o.pairs == FinetunePairs::Folds
            ? "fold " + std::to_string(f + 1) + "/" + std::to_string(groups.size())
            : to_string(o.pairs);
    core::ProgressBar bar(label, n);
    for (int64_t i = 0; i < n; ++i) {
      if (g_stop) throw core::Error(run_.root, "interrupted while training the auxiliary models");
      t->advance();
      bar.update(t->state_.iteration);
    }
    bar.finish();
    torch::NoGradGuard no_grad;
    const torch::Tensor offsets = t->band_offsets();
    // At the views' own poses (the main scene's cameras: a perturbed model's
    // are turned).
    for (int v : groups[f])
      renders[v] = eval::render_view(*scene_, t->state_.gaussians, t->background_, v, offsets);
  }
  std::string who;
  if (o.pairs == FinetunePairs::Folds)
    who = std::to_string(groups.size()) + " auxiliary models that never saw them (" +
          std::to_string(steps) + " iterations each";
  else if (o.pairs == FinetunePairs::Checkpoint)
    who = "the Gaussians as they were at iteration " + std::to_string(steps) + " (recomputed";
  else {
    char px[32];
    std::snprintf(px, sizeof px, "%g", o.perturb_px);
    who = "a model trained on them with each camera turned by " + std::string(px) + " px (" +
          std::to_string(steps) + " iterations";
  }
  core::log_info(
      "denoiser pairs: " + std::to_string(renders.size()) + " training views rendered by " + who +
      ", " +
      core::format_duration(
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()) +
      ")");
  return renders;
}

void Trainer::make_pseudo_views(int64_t iteration) {
  const DiffusionTermOptions& o = diffusion_->options();
  std::vector<core::Camera> train_cameras;
  for (int v : scene_->train) train_cameras.push_back(scene_->views[v].camera);
  std::vector<core::Camera> cameras = between_cameras(train_cameras);
  if (cameras.empty())
    throw core::Error(run_.root, "distillation needs at least two training views");
  // As many as the fine-tuning's memory budget holds, evenly spread.
  const auto& in = cameras.front().intrinsics;
  const double bytes = double(in.width) * double(in.height) * double(scene_->bands()) * 4.0;
  const size_t fit = size_t(std::max(1.0, double(o.finetune_cache_mb) * 1048576.0 / bytes));
  if (cameras.size() > fit) {
    std::vector<core::Camera> kept;
    for (size_t i = 0; i < fit; ++i) kept.push_back(cameras[i * cameras.size() / fit]);
    core::log_info("distillation: " + std::to_string(fit) + " of " +
                   std::to_string(cameras.size()) +
                   " pseudo-views fit diffusion.finetune_cache_mb");
    cameras = kept;
  }
  const fs::path file = run_.pseudo_views();
  if (iteration > finetune_end() + 1 && fs::exists(file)) {
    const std::string unreadable = "unreadable or truncated: start the run again with --force";
    torch::serialize::InputArchive archive;
    read_archive(file, archive, unreadable);
    torch::Tensor targets;
    if (!archive.try_read("targets", targets)) throw core::Error(file, unreadable);
    if (targets.dim() != 4 || targets.size(0) != int64_t(cameras.size()))
      throw core::Error(file, "does not hold this run's pseudo-views");
    for (size_t i = 0; i < cameras.size(); ++i)
      pseudo_views_.push_back({cameras[i], targets[int64_t(i)]});
    return;
  }
  if (iteration > finetune_end() + 1)
    throw core::Error(file,
                      "missing: the distillation cannot resume without its pseudo-views; "
                      "resume with --iterations to redo the stage");
  core::TorchThreads torch_threads;  // the denoiser's convolutions
  torch::NoGradGuard no_grad;
  const torch::Tensor offsets = band_offsets();
  core::ProgressBar bar("pseudo-views", int64_t(cameras.size()));
  std::vector<torch::Tensor> targets;
  for (size_t i = 0; i < cameras.size(); ++i) {
    const torch::Tensor render =
        model::render_gaussians(state_.gaussians, cameras[i], background_, offsets).image;
    model::SamplerOptions sampler = o.sampler;
    sampler.seed = mix_seed(config_.seed, kTermStream + uint64_t(iteration) + i);
    targets.push_back(model::denoise_view(diffusion_->denoiser(), render, sampler));
    pseudo_views_.push_back({cameras[i], targets.back()});
    bar.update(int64_t(i) + 1);
  }
  bar.finish();
  torch::serialize::OutputArchive archive;
  archive.write("targets", torch::stack(targets));
  write_archive(file, archive);
}

json Trainer::distill_step(int64_t iteration) {
  if (denoiser_validation_.is_null()) {
    // Resumed after the fine-tuning: the same verdict again.
    if (!finetuning_) finetune_step_setup();
    validate_denoiser();
  }
  if (!distilling_) {
    distilling_ = true;  // decided once per process
    const bool gained = !denoiser_validation_.contains("psnr_denoised") ||
                        denoiser_validation_["psnr_denoised"].get<double>() >
                            denoiser_validation_["psnr_render"].get<double>();
    if (gained) {
      make_pseudo_views(iteration);
    } else if (iteration == finetune_end() + 1) {
      core::log_warn(
          "distillation skipped: the denoiser made the views it did not learn from worse, so "
          "its pseudo-views would teach the Gaussians its errors; the " +
          std::to_string(diffusion_->options().distill_steps) +
          " iterations left train on the training views only");
    }
  }
  const int64_t every = diffusion_->options().distill_every;
  const int64_t k = iteration - finetune_end() - 1;
  const bool on_pseudo = !pseudo_views_.empty() && k % every == every - 1;
  const size_t p = on_pseudo ? size_t(k / every) % pseudo_views_.size() : 0;
  json record = step(iteration, on_pseudo ? &pseudo_views_[p] : nullptr);
  record["phase"] = "distill";
  if (on_pseudo) record["pseudo_view"] = p;
  return record;
}

void Trainer::save(bool numbered) {
  require_finite_parameters(state_, run_.root);
  state_.model_record = model_record(config_, *scene_);
  save_checkpoint(run_.checkpoint(), state_);
  if (writer_) writer_->saved(state_.iteration);
  if (numbered) {
    io::copy_file_atomically(run_.checkpoint(), run_.checkpoint_at(state_.iteration));
  }
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

void Trainer::write_outputs(double seconds, const json& test_at_end) {
  // The encoder's offsets are added to the exported coefficients, so any
  // renderer of the PLY sees what training saw.
  torch::Tensor offsets;
  {
    torch::NoGradGuard no_grad;
    offsets = band_offsets();
  }
  io::write_gaussian_ply(run_.gaussians(),
                         model::to_ply(state_.gaussians, scene_->wavelengths_nm, offsets));
  const int64_t iterations = config_.iterations;
  const int degree = state_.gaussians.max_sh_degree();
  // Time of the Gaussian iterations alone (the denoiser's fine-tuning after
  // them is reported apart).
  const double gaussian_seconds =
      state_.counters.gaussian_seconds >= 0 ? state_.counters.gaussian_seconds : seconds;
  json summary = {
      {"iterations", iterations},
      {"seconds", seconds},
      {"iterations_per_second", gaussian_seconds > 0 ? double(iterations) / gaussian_seconds : 0.0},
      {"num_gaussians", state_.gaussians.size()},
      {"bands", scene_->bands()},
      {"sh_degree", degree},
      {"colour_channels", state_.gaussians.channels()},
      {"bytes_per_gaussian",
       model::training_bytes_per_gaussian(state_.gaussians.channels(), degree)},
      {"peak_rss_mib", peak_rss_mib()},
      {"threads", core::thread_count()},
      {"thread_source", core::thread_source()},
      {"densify_added", state_.counters.densify_added},
      {"densify_removed", state_.counters.densify_removed}};
  if (offsets.defined()) {
    // How far the encoder moved the SH coefficients, to judge its effect.
    summary["wavelength_offsets_abs_max"] = offsets.abs().max().item<double>();
    summary["wavelength_offsets_rms"] = offsets.pow(2).mean().sqrt().item<double>();
  }
  if (diffusion_ && diffusion_->options().finetune_steps > 0) {
    summary["denoiser_finetune_steps"] = diffusion_->options().finetune_steps;
    // Everything after the Gaussian iterations: auxiliary models, fine-tuning
    // and distillation.
    summary["denoiser_finetune_seconds"] = seconds - gaussian_seconds;
  }
  if (diffusion_) {
    if (!denoiser_validation_.is_null()) summary["denoiser_validation"] = denoiser_validation_;
    summary["denoiser_pairs"] = to_string(diffusion_->options().pairs);
    if (!denoiser_pairs_psnr_.is_null()) summary["denoiser_pairs_psnr"] = denoiser_pairs_psnr_;
    summary["distill_steps"] = diffusion_->options().distill_steps;
    summary["pseudo_views"] = pseudo_views_.size();
  }
  if (exposure_) {
    const json gains = exposure_summary(*exposure_, *scene_);
    core::log_info(describe_exposure(gains));
    summary.update(gains);
  }
  summary.update(test_at_end.is_null() ? test_psnr() : test_at_end);
  if (rig_refinement_)
    summary["rig_corrections"] = rig_refinement_->report(*scene_, extent_, run_.rig_corrections());
  if (diffusion_) write_denoiser(denoiser_path(run_), diffusion_->denoiser());
  if (background_module_ || config_.model.background_from_views) {
    // eval, render and report take it from here (config.json stays as the
    // run was configured, so the run can be reproduced from it).
    auto values = background_.detach().contiguous();
    json learned = {{"background", std::vector<float>(values.data_ptr<float>(),
                                                      values.data_ptr<float>() + values.numel())}};
    io::write_file_atomically(run_.learned_background(), learned.dump(2) + "\n");
  }
  io::write_file_atomically(run_.summary(), summary.dump(2) + "\n");
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
  g_stop = false;
  g_stop_signal = 0;
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
      if (g_stop) return false;
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
  // The training-view PSNR of the last record that measured it (keeps_record).
  double shown_psnr = std::nan("");
  auto gaussian_status = [&shown_psnr](const json& record) {
    if (record.contains("train_psnr")) shown_psnr = record["train_psnr"].get<double>();
    char psnr_text[40] = "";
    if (!std::isnan(shown_psnr))
      std::snprintf(psnr_text, sizeof psnr_text, "  psnr %.2f dB", shown_psnr);
    char text[160];
    std::snprintf(text, sizeof text, "loss %.4f%s  G %lld", record["loss"].get<double>(), psnr_text,
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
          iterations, [this](int64_t i) { return step(i); }, gaussian_status) &&
      run_phase(
          finetune_end(), [this](int64_t i) { return finetune_step(i); }, finetune_status) &&
      run_phase(
          total, [this](int64_t i) { return distill_step(i); }, gaussian_status);
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
