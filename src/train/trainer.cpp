#include "train/trainer.h"

#include <ATen/CPUGeneratorImpl.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <functional>
#include <optional>

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
#include "train/config.h"
#include "train/init.h"
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

bool every(int64_t iteration, int64_t interval) {
  return interval > 0 && iteration % interval == 0;
}

}  // namespace

uint64_t mix_seed(uint64_t seed, uint64_t stream) {
  uint64_t z = seed + 0x9e3779b97f4a7c15ULL * (stream + 1);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

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
  io::log_scene_messages(*scene_);
  core::require(!scene_->train.empty(), data, "the dataset has no training views");
  check_scene_before_training(*scene_);
  background_ = background(config_.model, scene_->bands());
  if (config_.model.background_from_views) {
    background_ = io::border_colour(*scene_, scene_->train);
    core::log_info("background starts from the training views' border colour (" +
                   io::describe_colour(background_) + ")");
  }
  extent_ = scene_extent(*scene_, scene_->train);
  const LossConfig& loss = config_.loss;
  losses_ = baseline_losses(loss.l1, loss.dssim);
  losses_.push_back(spectral_term(loss.spectral, loss.spectral_options));
  build_modules();
}

void Trainer::build_modules() {
  colour_ =
      initial_colour_model(*scene_, config_.model.spectral_rank, config_.model.subspace_from_bands);
  if (colour_.latent()) {
    colour_module_ = std::make_shared<torch::nn::Module>();
    colour_.basis = colour_module_->register_parameter("basis", colour_.basis.clone());
    colour_.mean = colour_module_->register_parameter("mean", colour_.mean.clone());
    add_module("colour_model", colour_module_, config_.optim.basis_lr);
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
    add_module("background", background_module_, config_.optim.background_lr);
  }
  if (config_.camera_refinement.enabled) {
    camera_refinement_ = CameraRefinement(int64_t(scene_->views.size()), scene_->train);
    add_module("camera_refinement", camera_refinement_.ptr(),
               config_.camera_refinement.rotation_lr);
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
    losses_.push_back(diffusion_->loss_term());
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
  state_.adam.group("log_scales").lr = o.scaling_lr;
  state_.adam.group("quats").lr = o.rotation_lr;
  state_.adam.group("logit_opacities").lr = o.opacity_lr;
  const double sh_lr = o.sh_dc_lr * state_.gaussians.colour.sh_rate_scale(o.latent_sh_lr_scale);
  state_.adam.group("sh_dc").lr = sh_lr;
  state_.adam.group("sh_rest").lr = sh_lr / o.sh_rest_lr_divisor;
  if (camera_refinement_)
    state_.adam.group("camera_refinement/translation").lr =
        config_.camera_refinement.translation_lr;
}

render::RenderOutput Trainer::render_training_view(int view, const torch::Tensor& sink,
                                                   const render::ShRestSink& rest_step) {
  const core::Camera& camera = scene_->views[view].camera;
  model::Gaussians g = state_.gaussians;  // handles to the same tensors
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
  InitOptions options = t->config_.init;
  options.seed = mix_seed(t->config_.seed, 0);
  t->state_.gaussians = initialise_gaussians(*t->scene_, options, t->colour_);
  t->state_.stats.reset(t->state_.gaussians.size());
  t->create_optimizer();
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
  return t;
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
  t->load_scene();
  model::AdamOptions options;
  options.eps = t->config_.optim.adam_eps;
  load_checkpoint(run.checkpoint(), t->state_, options);
  t->attach_colour();
  if (t->state_.gaussians.channels() != t->colour_.channels(t->scene_->bands()))
    throw core::Error(run.checkpoint(),
                      "has " + std::to_string(t->state_.gaussians.channels()) +
                          " colour channels per Gaussian but the run's colour "
                          "model has " +
                          std::to_string(t->colour_.channels(t->scene_->bands())));
  if (t->state_.gaussians.bands() != t->scene_->bands())
    throw core::Error(run.checkpoint(), "has " + std::to_string(t->state_.gaussians.bands()) +
                                            " bands but the dataset loads " +
                                            std::to_string(t->scene_->bands()));
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
    load_checkpoint(run.checkpoint(), t->state_, options);
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

json Trainer::step(int64_t iteration) {
  core::StageScope step_scope("step (other)");
  // The denoiser's convolutions are large enough for LibTorch's own threads.
  std::optional<core::TorchThreads> torch_threads;
  if (diffusion_ && iteration > diffusion_->options().warmup) torch_threads.emplace();
  set_learning_rates(iteration);
  auto& g = state_.gaussians;
  if (every(iteration, schedule_.sh_degree_every) && g.active_sh_degree < g.max_sh_degree())
    ++g.active_sh_degree;

  const int view = view_for(iteration);
  const core::Camera& camera = scene_->views[view].camera;
  torch::Tensor target;
  {
    core::StageScope stage("view (to float)");
    target = scene_->image(view);
  }
  auto sink = torch::zeros({g.size(), 2}).requires_grad_(true);
  render::RenderOutput out;
  {
    core::StageScope stage("render (other)");
    // Adam updates the SH rest coefficients block by block inside the SH
    // backward: their [G, N, 15] gradient is never stored.
    render::ShRestSink rest_step;
    if (g.sh_rest.numel() > 0) rest_step = state_.adam.row_step("sh_rest");
    out = render_training_view(view, sink, rest_step);
  }
  // A view of a band-per-view scene supervises only the bands it holds.
  const torch::Tensor rendered = scene_->view_slice(view, out.image);
  LossValues loss;
  {
    core::StageScope stage("losses (other)");
    loss = evaluate_losses(losses_, {rendered, target, view, iteration,
                                     mix_seed(config_.seed, kTermStream + uint64_t(iteration))});
  }
  {
    core::StageScope stage("backward (other)");
    loss.total.backward();
  }

  if (schedule_.densifies(iteration) && sink.grad().defined()) {
    core::StageScope stage("densify stats");
    state_.stats.accumulate(out.radii, sink.grad(), camera.intrinsics.width,
                            camera.intrinsics.height);
  }
  {
    core::StageScope stage("adam");
    state_.adam.step();
    state_.adam.zero_grad();
    if (camera_refinement_) camera_refinement_->recentre();
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
                      " -> " + std::to_string(g.size()));
    }
    if (every(iteration, reset_every)) model::reset_opacity(g, state_.adam);
  }

  core::StageScope stage("metrics");
  json record = {{"iter", iteration}, {"loss", loss.total.item<double>()}};
  for (const auto& [name, value] : loss.terms) record[name] = value;
  record["train_psnr"] = psnr(rendered, target);
  record["num_gaussians"] = g.size();
  record["densify_added"] = state_.counters.densify_added;
  record["densify_removed"] = state_.counters.densify_removed;
  return record;
}

json Trainer::advance() {
  const int64_t iteration = state_.iteration + 1;
  json record = step(iteration);
  state_.iteration = iteration;
  return record;
}

int64_t Trainer::total_steps() const {
  return config_.iterations + (diffusion_ ? diffusion_->options().finetune_steps : 0);
}

json Trainer::finetune_step(int64_t iteration) {
  core::TorchThreads torch_threads;  // the denoiser's convolutions
  if (!finetuning_)
    finetuning_ = std::make_unique<DenoiserFinetuning>(*diffusion_, *scene_, [this](int v) {
      torch::NoGradGuard no_grad;
      return render_training_view(v, {}).image;
    });
  json record = finetuning_->step(iteration - config_.iterations - 1, state_.adam,
                                  mix_seed(config_.seed, kTermStream + uint64_t(iteration)));
  record["iter"] = iteration;
  return record;
}

void Trainer::save(bool numbered) {
  require_finite_parameters(state_, run_.root);
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
    const torch::Tensor image = scene_->view_slice(
        v, eval::render_view(*scene_, state_.gaussians, background_, v, offsets).clamp(0, 1));
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
    summary["denoiser_finetune_seconds"] = seconds - gaussian_seconds;
  }
  summary.update(test_at_end.is_null() ? test_psnr() : test_at_end);
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
  const int64_t log_every = config_.output.log_every;
  const int64_t checkpoint_every = config_.output.checkpoint_every;
  const int64_t test_every = config_.output.test_every;
  MetricsLog metrics(run_.metrics(), state_.iteration);
  StopSignalGuard guard;
  g_stop = false;
  g_stop_signal = 0;
  const double seconds_before = state_.counters.seconds;
  const auto start = std::chrono::steady_clock::now();
  double measuring = 0;  // seconds spent on test-view records, not training
  json test_at_end;      // the record's test PSNR at the last Gaussian iteration, if taken
  auto elapsed = [&] {
    return seconds_before - measuring +
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
      // curve); rendering the test views changes no state, so resume stays
      // bit for bit.
      const bool test = iteration <= iterations && every(iteration, test_every);
      if (test) {
        const auto measure_start = std::chrono::steady_clock::now();
        const json measured = test_psnr();
        record.update(measured);
        if (iteration == iterations) test_at_end = measured;
        measuring +=
            std::chrono::duration<double>(std::chrono::steady_clock::now() - measure_start).count();
      }
      // The first and last of the run and the first of the fine-tuning.
      if (test || every(iteration, log_every) || iteration == total || iteration == 1 ||
          iteration == iterations + 1) {
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
  auto gaussian_status = [](const json& record) {
    char text[160];
    std::snprintf(text, sizeof text, "loss %.4f  psnr %.2f dB  G %lld",
                  record["loss"].get<double>(), record["train_psnr"].get<double>(),
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
  const bool finished = run_phase(
                            iterations, [this](int64_t i) { return step(i); }, gaussian_status) &&
                        run_phase(
                            total, [this](int64_t i) { return finetune_step(i); }, finetune_status);
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
  write_outputs(state_.counters.seconds, test_at_end);
  bar.finish();
  return TrainStatus::Finished;
}

}  // namespace ddhgs::train
