// The training loop of N-band Gaussian splatting (issue 4): one training view
// per iteration, weighted losses, fused Adam, adaptive density control,
// metrics, checkpoints and bit-for-bit resume. Files: train/run_folder.h.
#pragma once
#include <nlohmann/json.hpp>

#include <atomic>
#include <filesystem>
#include <memory>
#include <vector>

#include "io/dataset.h"
#include "model/gaussians.h"
#include "train/checkpoint.h"
#include "train/losses.h"
#include "train/run_folder.h"

namespace ddhgs::train {

enum class TrainStatus { Finished, Interrupted };

class Trainer {
 public:
  // A new run: creates the run folder (see create_run_folder), loads the
  // scene from config["data"]["path"] and initialises the Gaussians.
  static std::unique_ptr<Trainer> start(const nlohmann::json& config, const RunPaths& run,
                                        bool force);
  // Continues RUN from RUN/checkpoint.pt; iterations > 0 replaces the total.
  static std::unique_ptr<Trainer> resume(const RunPaths& run, int64_t iterations = 0);

  // Trains up to the configured iteration count; on SIGINT (or when
  // request_stop() is called) saves a checkpoint and returns Interrupted.
  TrainStatus run();

  // Loss terms; later components append their own before run().
  std::vector<LossTerm>& losses() { return losses_; }
  TrainState& state() { return state_; }
  const io::Scene& scene() const { return *scene_; }
  const nlohmann::json& config() const { return config_; }
  double extent() const { return extent_; }

  static void request_stop();

 private:
  Trainer(nlohmann::json config, RunPaths run);
  void load_scene();
  void create_optimizer();
  void set_learning_rates(int64_t iteration);
  int view_for(int64_t iteration) const;
  void step(int64_t iteration, nlohmann::json& record);
  void save(bool numbered);
  void write_outputs(double seconds);
  // Mean PSNR (dB) of the held-out views, against noisy and clean ground truth.
  nlohmann::json test_psnr() const;

  nlohmann::json config_;
  RunPaths run_;
  std::unique_ptr<io::Scene> scene_;
  TrainState state_;
  std::vector<LossTerm> losses_;
  torch::Tensor background_;  // [N]
  double extent_ = 1;
  bool replacing_ = false;
};

}  // namespace ddhgs::train
