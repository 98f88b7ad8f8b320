// The training loop of N-band Gaussian splatting: one training view
// per iteration, weighted losses, fused Adam, adaptive density control,
// metrics, checkpoints and bit-for-bit resume. Files: train/run_folder.h.
// With the denoiser on, the diffusion stage (train/diffusion_stage.h) follows
// the `iterations` joint steps; the iteration counter runs on through it, and
// the checkpoint at the end of the joint steps is kept. How a trainer is made
// (a new run, a resumed one, an auxiliary model): trainer_setup.cpp; what it
// writes: trainer_outputs.cpp.
#pragma once
#include <nlohmann/json.hpp>

#include <filesystem>
#include <memory>
#include <optional>
#include <vector>

#include "io/blocks/block_grid.h"
#include "io/scene/scene.h"
#include "model/gaussians.h"
#include "model/wavelength_encoder.h"
#include "train/camera_refinement.h"
#include "train/checkpoint.h"
#include "train/diffusion_term.h"
#include "train/exposure_correction.h"
#include "train/losses.h"
#include "train/rig_refinement.h"
#include "train/run_config.h"
#include "train/run_folder.h"
#include "train/schedule.h"
#include "train/stage_host.h"
#include "train/view_crop.h"

namespace ddhgs::train {

enum class TrainStatus { Finished, Interrupted };

class DiffusionStage;

class Trainer : private StageHost {
 public:
  // A new run: loads the scene from config["data"]["path"], initialises the
  // Gaussians, then creates the run folder (RunWriter::create; `replace` is
  // --force), so bad input leaves an existing folder untouched.
  static std::unique_ptr<Trainer> start(const nlohmann::json& config, const RunPaths& run,
                                        bool replace);
  // Continues RUN from RUN/checkpoint.pt; iterations > 0 replaces the total.
  static std::unique_ptr<Trainer> resume(const RunPaths& run, int64_t iterations = 0);

  ~Trainer();

  // Trains up to the configured iteration count; on SIGINT or SIGTERM (or
  // when train::request_stop() is called, train/stop_signal.h) saves a
  // checkpoint and returns Interrupted. When it throws, the run folder is
  // kept if it holds a checkpoint, else removed (and a run it replaced
  // restored).
  TrainStatus run();
  // One Gaussian iteration after state().iteration, without metrics,
  // checkpoints or outputs (benchmarks); returns its metrics record.
  nlohmann::json advance();

  // Loss terms; later components append their own before run().
  std::vector<LossTerm>& losses() { return losses_; }
  // Adds a network trained beside the Gaussians (train/checkpoint.h
  // TrainedModule). Call while the trainer is built (build_modules), before the
  // optimizer is created or a checkpoint is read.
  void add_module(const std::string& name, std::shared_ptr<torch::nn::Module> module, double lr);
  // The wavelength encoder's output per band [N, width]
  // (model::ColourModel::encoder_width: SH offsets per band, or a latent
  // basis row's), or an undefined tensor when the encoder is off.
  // Differentiable.
  torch::Tensor band_offsets();
  TrainState& state() override { return state_; }
  const io::Scene& scene() const override { return *scene_; }
  const RunConfig& config() const override { return config_; }
  double extent() const { return extent_; }

 private:
  // The trained modules with one row per band (Adam groups "<module>/<name>"),
  // and the one with a row per view.
  static constexpr const char* kColourModule = "colour_model";
  static constexpr const char* kBackgroundModule = "background";
  static constexpr const char* kExposureModule = "exposure";
  class Auxiliary;  // an auxiliary model, as auxiliary() returns it

  Trainer(RunConfig config, RunPaths run);
  void load_scene();
  // The colour model and the networks beside the Gaussians, from the config
  // (both start and resume; a resumed run checks its checkpoint first).
  void build_modules();
  void create_optimizer();
  // Fresh Gaussians from the loaded scene (init section, the run's seed),
  // their densification statistics and the optimizer: a new run's, or an
  // auxiliary model's (train/denoiser_pairs.h).
  void initialise();
  void set_learning_rates(int64_t iteration);
  // The training view step `iteration` renders: a fresh permutation of the
  // training views every epoch, seeded by epoch; a rig run's warm-up draws
  // from its reference camera's views alone. A block trained as part of its
  // flight draws from the flight's training views: kElsewhere when the
  // step's view is not one of the block's.
  static constexpr int kElsewhere = -1;
  int view_for(int64_t iteration) const;
  // A step whose view lies elsewhere in the flight: the Gaussians move on
  // their Adam momentum (model::Adam::coast), densification and the test
  // record go on as scheduled; the record has no loss.
  nlohmann::json coast(int64_t iteration);
  // The held-out views' PSNR into step_test_ when the step takes a test record.
  void measure_test_views(int64_t iteration);
  // Densification and opacity resets as scheduled after step `iteration`.
  void densify_after(int64_t iteration);
  // The block's cell and margin on the step's view (crop: its part of the
  // view; null: the whole view): [H, W, 1] bool, where the loss applies.
  torch::Tensor block_loss_mask(const core::Camera& camera, const ViewCrop* crop, int64_t height,
                                int64_t width) const;
  // One info line on how a block trains as part of its flight.
  void log_block() const;
  // A training view rendered with its camera correction, if any; sink as in
  // render::rasterize; rest_step receives the SH rest gradient in blocks;
  // band_map ([M, N], may be undefined) picks the bands rendered; crop (may
  // be null) renders only that part of the view.
  render::RenderOutput render_training_view(int view, const torch::Tensor& sink,
                                            const render::ShRestSink& rest_step = {},
                                            const torch::Tensor& band_map = {},
                                            const ViewCrop* crop = nullptr);
  // One info line when the steps measure crops of their views.
  void log_crops() const;
  // The fraction of a width x height training view a cropped step measures
  // (train::crop_fraction; 1 with the joint diffusion term).
  double view_fraction(int width, int height) const;
  // The part of a width x height training view iteration measures
  // (loss.view_fraction and view_fraction_from_pixels, train/view_crop.h), or nullopt
  // for the whole view.
  std::optional<ViewCrop> step_crop(int64_t iteration, int width, int height) const;
  // The bands iteration measures (loss.bands_per_step, train/band_draw.h) on
  // training view `view`, or undefined for all of them.
  torch::Tensor step_bands(int64_t iteration, int view) const;
  // core::selection_map of those bands; undefined for undefined bands.
  torch::Tensor band_map(const torch::Tensor& bands) const;
  // One Gaussian iteration (1-based) on a training view, or on `pseudo` with
  // its losses scaled by diffusion.distill_weight; returns its metrics record
  // (train_psnr only where keeps_record).
  nlohmann::json step(int64_t iteration, const PseudoView* pseudo) override;
  // StageHost: the run folder, renders without autograd, auxiliary models.
  const RunPaths& run_paths() const override { return run_; }
  torch::Tensor render_view(int view) override;
  torch::Tensor render_camera(const core::Camera& camera) override;
  std::unique_ptr<AuxiliaryModel> auxiliary(const RunConfig& config,
                                            const std::vector<int>& held_out,
                                            double perturb_px) override;
  // Whether metrics.jsonl keeps step `iteration`'s record: every
  // output.log_every and output.test_every steps, the first, the last of the
  // Gaussian iterations plus one, and the last. Only those measure the
  // training view's PSNR (about 47 ms a step at 640x512x141).
  bool keeps_record(int64_t iteration) const;
  // Whether step `iteration` renders the test views for their PSNR
  // (output.test_every, Gaussian iterations only).
  bool measures_test_views(int64_t iteration) const;
  // Gaussian iterations plus the denoiser's fine-tuning and distillation
  // steps, if any.
  int64_t total_steps() const;
  // The last fine-tuning step (the Gaussian iterations when there is none).
  int64_t finetune_end() const;
  TrainStatus run_steps();
  void save(bool numbered);
  // test_at_end: test_psnr() already taken at the last Gaussian iteration
  // (null: measured here); the denoiser's fine-tuning does not change it.
  void write_outputs(double seconds, const nlohmann::json& test_at_end);
  // Mean PSNR (dB) of the held-out views, against noisy and clean ground truth.
  nlohmann::json test_psnr();
  // The test records, taken inside step(): the seconds test_psnr() took
  // there, which the run's training time leaves out, and the figures of the
  // latest step's record (null when that step took none).
  double test_seconds_ = 0;
  nlohmann::json step_test_;

  RunConfig config_;
  RunPaths run_;
  Schedule schedule_;  // from config_ (resume with new iterations rebuilds the trainer)
  std::unique_ptr<io::Scene> scene_;
  TrainState state_;
  std::vector<LossTerm> losses_;
  torch::Tensor background_;  // [N]
  double extent_ = 1;
  // A block of a flight (io::read_block_context) trained as part of it
  // (data.block_as_flight).
  std::optional<io::BlockContext> block_;
  // A block whose run would learn its background draws over its flight's
  // backdrop (block.json), not learned.
  bool draws_flights_backdrop() const {
    return block_ && config_.model.learn_background && !block_->background.empty();
  }
  // The training views the steps draw from: the flight's for such a block,
  // else the scene's own.
  int64_t schedule_views() const;
  model::WavelengthEncoder encoder_{nullptr};
  CameraRefinement camera_refinement_{nullptr};  // camera_refinement.enabled
  ExposureCorrection exposure_{nullptr};         // model.exposure_correction
  RigRefinement rig_refinement_{nullptr};        // camera_refinement.rig
  bool aligning_rig_ = false;                    // this step is in the rig's alignment phase
  std::vector<int> reference_train_;             // its reference camera's training views
  std::unique_ptr<DiffusionTerm> diffusion_;     // loss.diffusion > 0
  std::unique_ptr<DiffusionStage> stage_;        // with diffusion_
  torch::Tensor wavelengths01_;                  // [N] the encoder's input
  bool resuming_ = false;                        // made by resume(): the checkpoint's state
  int64_t resumed_rank_ = 0;  // the checkpoint's colour model (ColourModel::rank)
  // An auxiliary model of the denoiser's pairs: quiet about the scene; its training
  // views leave held_out_ out, and its training cameras are turned so that
  // their images move by perturb_px_ pixels.
  bool auxiliary_ = false;
  std::vector<int> held_out_;
  double perturb_px_ = 0;
  // Holds a latent colour model's basis and mean as trained parameters;
  // attach_colour() hands them to the Gaussians.
  std::shared_ptr<torch::nn::Module> colour_module_;
  model::ColourModel colour_;  // the starting colour model, from the config
  void attach_colour();
  // Holds background_ as a trained parameter when model.learn_background is on.
  std::shared_ptr<torch::nn::Module> background_module_;
  std::unique_ptr<RunWriter> writer_;
};

}  // namespace ddhgs::train
