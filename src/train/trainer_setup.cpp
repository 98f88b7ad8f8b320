// How a Trainer is made: a new run (start), a resumed one (resume), and an
// auxiliary model of the denoiser's pairs (auxiliary); for each, the scene,
// the colour model and the networks beside the Gaussians, and the optimizer.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/error.h"
#include "core/log.h"
#include "core/text.h"
#include "io/blocks/block_grid.h"
#include "io/files/atomic_file.h"
#include "io/scene/backdrop.h"
#include "train/config.h"
#include "train/denoiser_prior.h"
#include "train/diffusion_stage.h"
#include "train/init.h"
#include "train/model_shape.h"
#include "train/novel_views.h"
#include "train/run_checks.h"
#include "train/seed.h"
#include "train/trainer.h"

namespace ddhgs::train {

namespace fs = std::filesystem;
using nlohmann::json;

// An auxiliary Trainer as the diffusion stage sees it.
class Trainer::Auxiliary : public AuxiliaryModel {
 public:
  explicit Auxiliary(std::unique_ptr<Trainer> trainer) : trainer_(std::move(trainer)) {}
  void advance() override { trainer_->advance(); }
  torch::Tensor render(const core::Camera& camera) override {
    return trainer_->render_camera(camera);
  }

 private:
  std::unique_ptr<Trainer> trainer_;
};

Trainer::Trainer(RunConfig config, RunPaths run)
    : config_(std::move(config)), run_(std::move(run)), schedule_(schedule_of(config_)) {}

std::unique_ptr<Trainer> Trainer::start(const json& config, const RunPaths& run, bool replace) {
  RunConfig parsed = parse_run_config(config, "config");
  const std::vector<fs::path> inputs = {parsed.data.path};
  RunWriter::check(run, replace, inputs);  // before the work of loading
  std::unique_ptr<Trainer> t(new Trainer(std::move(parsed), run));
  t->load_scene();  // before touching the output, so bad input leaves it intact
  json written = config;
  // A block of a flight runs the flight's schedule, so its length follows the
  // flight's training views.
  const int64_t schedule_views = t->schedule_views();
  const int64_t length = run_iterations(t->config_, t->scene_->band_per_view(), schedule_views);
  if (length != t->config_.iterations) {
    core::log_info("training for " + std::to_string(length) + " iterations (" +
                   std::to_string(t->config_.optim.iterations_per_band_view) + " per view of " +
                   std::to_string(schedule_views) +
                   " training band images: optim.iterations_per_band_view on a band-per-view "
                   "scene; --iterations N sets the length)");
    t->config_.iterations = length;
    t->config_.resolved["iterations"] = length;
    written["iterations"] = length;
    t->schedule_ = schedule_of(t->config_);
  }
  t->build_modules();
  t->initialise();
  // Every file the run will read, resolved before anything is moved: a cube
  // inside the folder being replaced would go with it.
  std::vector<fs::path> read = inputs;
  for (const io::View& v : t->scene_->views) {
    read.push_back(v.data_path);
    if (!v.clean_path.empty()) read.push_back(v.clean_path);
  }
  t->writer_ = RunWriter::create(run, written, replace, read);
  core::log_info("training " + std::to_string(t->state_.gaussians.size()) + " Gaussians x " +
                 std::to_string(t->scene_->bands()) + " bands on " +
                 std::to_string(t->scene_->train.size()) + " views (" +
                 std::to_string(t->scene_->test.size()) + " held out)");
  t->log_crops();
  t->log_block();
  return t;
}

void Trainer::log_block() const {
  if (!block_) return;
  const int64_t own = int64_t(scene_->train.size());
  const int64_t flight = block_->flight_train_views;
  core::log_info(block_->name + " of a flight of " + std::to_string(flight) +
                 " training views, trained as the flight's model would have trained its ground "
                 "(data.block_as_flight): " +
                 std::to_string(own) + " of every " + std::to_string(flight) +
                 " steps render one of its views, the others move its Gaussians on momentum "
                 "alone; the flight's extent " +
                 core::fixed(extent_, 3) +
                 "; the loss only where the ground lies in its cell and margin. Give it the "
                 "iterations you would give the whole flight.");
  if (draws_flights_backdrop())
    core::log_info(block_->name + " draws over the flight's backdrop (" +
                   io::describe_colour(background_.detach()) +
                   ", block.json), as every block of the flight does: its background is not "
                   "learned");
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

std::unique_ptr<AuxiliaryModel> Trainer::auxiliary(const RunConfig& config,
                                                   const std::vector<int>& held_out,
                                                   double perturb_px) {
  std::unique_ptr<Trainer> t(new Trainer(config, run_));
  t->auxiliary_ = true;
  t->held_out_ = held_out;
  t->perturb_px_ = perturb_px;
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
  return std::make_unique<Auxiliary>(std::move(t));
}

void Trainer::load_scene() {
  const fs::path& data = config_.data.path;
  core::require(!data.empty(), run_.config(), "data.path is empty: no dataset to train on");
  scene_ = io::load_scene(data, config_.data.load);
  if (!auxiliary_) {
    io::log_scene_messages(*scene_);
  } else {  // an auxiliary model (train/denoiser_pairs.h): the main run said it all
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
  // A block of a flight trains as the flight's model would have trained its
  // ground (data.block_as_flight); an auxiliary model of the denoiser's pairs
  // trains on the scene alone.
  if (config_.data.block_as_flight && !auxiliary_) {
    block_ = io::read_block_context(data);
    if (block_) {
      const int64_t own = int64_t(scene_->train.size());
      if (block_->flight_train_views < own)
        throw core::Error(data / io::kBlockContextFile,
                          "flight_train_views: " + std::to_string(block_->flight_train_views) +
                              " is fewer than the block's own " + std::to_string(own) +
                              " training views (was the block's transforms.json edited?)");
      extent_ = block_->flight_extent;
      // Every block draws over the flight's one backdrop: a background each
      // learned from its own pixels would settle differently in each, and
      // with it what the Gaussians cover (docs/benchmarks.md, "One backdrop
      // for every block").
      if (draws_flights_backdrop()) {
        const std::vector<double>& bg = block_->background;
        if (int64_t(bg.size()) != scene_->bands())
          throw core::Error(data / io::kBlockContextFile,
                            "background: " + std::to_string(bg.size()) + " values for " +
                                std::to_string(scene_->bands()) + " bands");
        background_ = torch::tensor(bg, torch::kFloat64).to(torch::kFloat32);
      }
    }
  }
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
    // A block's flight backdrop stays as it is (a rate of zero keeps the
    // module, so the checkpoint, background.json and merge see it as ever).
    add_module(kBackgroundModule, background_module_,
               draws_flights_backdrop() ? 0.0 : config_.optim.background_lr);
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
  if (!config_.camera_refinement.rig && !config_.camera_refinement.rig_start.empty())
    throw core::Error(config_.camera_refinement.rig_start,
                      "is camera_refinement.rig_start, but camera_refinement.rig is off: the "
                      "corrections it holds would not be used (set camera_refinement.rig=true)");
  const CameraRefinementConfig& cameras = config_.camera_refinement;
  if (cameras.rig && cameras.rig_pivot && cameras.rig_offset_lr == 0 && cameras.rig_rotation_lr > 0)
    throw core::Error("camera_refinement.rig_pivot",
                      "moves each band camera's centre as it turns, so rig_offset_lr=0 would not "
                      "hold the offsets (known lever arms): set rig_pivot=false");
  if (config_.camera_refinement.rig) {
    for (int v : scene_->train)
      if (scene_->views[size_t(v)].rig_camera == scene_->rig->reference_camera)
        reference_train_.push_back(v);
    const double pivot = config_.camera_refinement.rig_pivot && !reference_train_.empty()
                             ? rig_pivot_depth(*scene_, reference_train_)
                             : 0.0;
    rig_refinement_ = RigRefinement(*scene_, pivot);
    // A resumed run's checkpoint holds its own (the file may be gone).
    const std::string& start = config_.camera_refinement.rig_start;
    if (!start.empty() && !resuming_) {
      rig_refinement_->start_from(io::read_rig_corrections(start, scene_->rig->unit_m), extent_,
                                  start);
      if (!auxiliary_) core::log_info("rig refinement: the band cameras start from " + start);
    }
    // Turns and offsets learned together trade against each other (a turn
    // and a sideways move shift the image alike); known lever arms avoid it.
    if (start.empty() && cameras.rig_offset_lr > 0 && cameras.rig_rotation_lr > 0 && !auxiliary_)
      core::log_info(
          "rig refinement: turns and offsets learn together; where the rig's lever arms are "
          "known, give them (camera_refinement.rig_start with offset_cm, rig_offset_lr=0) and the "
          "turns are found far closer (docs/commands.md)");
    if (pivot > 0 && !auxiliary_)
      core::log_info("rig refinement: band cameras turn about the point " + core::fixed(pivot, 3) +
                     " scene units ahead of them (camera_refinement.rig_pivot)");
    add_module("rig_refinement", rig_refinement_.ptr(), config_.camera_refinement.rig_rotation_lr);
  }
  DiffusionTermOptions diffusion = with_bands(config_.diffusion, scene_->bands());
  if (diffusion.enabled()) {
    // The denoiser sees every band of a view at once; a view that holds one
    // band has no such image.
    if (scene_->band_per_view())
      throw core::Error(scene_->root,
                        "is a band-per-view scene (each view holds some of the bands); the "
                        "diffusion stage needs every band of a view: train it with "
                        "loss.diffusion=0");
    if (diffusion.prior.empty())
      diffusion_ =
          std::make_unique<DiffusionTerm>(diffusion, mix_seed(config_.seed, kDenoiserInitStream));
    else
      diffusion_ = prior_term(diffusion, *scene_);
    add_module("denoiser", diffusion_->denoiser().unet.ptr(), diffusion.lr);
    if (diffusion.joint) losses_.push_back(diffusion_->loss_term());
    StageHost& host = *this;
    stage_ = std::make_unique<DiffusionStage>(host, *diffusion_);
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

void Trainer::create_optimizer() {
  model::AdamOptions options;
  options.eps = config_.optim.adam_eps;
  state_.adam = model::Adam(options);
  auto tensors = state_.gaussians.tensors();
  for (size_t i = 0; i < tensors.size(); ++i)
    state_.adam.add(model::Gaussians::tensor_names()[i], *tensors[i], 0.0);
  for (const auto& m : state_.modules) add_module_groups(state_.adam, m);
}

}  // namespace ddhgs::train
