// train::check_resumable: a run resumes only under a config that builds the
// model its checkpoint holds; each refusal names the setting, both values
// and both files.
#include <gtest/gtest.h>

#include "support/error_text.h"
#include "train/config.h"
#include "train/model_shape.h"

namespace ddhgs::train {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;

RunConfig config_with(const std::vector<std::string>& assignments) {
  json config = load_preset("demo");
  for (const std::string& a : assignments) apply_assignment(config, a);
  return parse_run_config(config, "run/config.json");
}

// A scene of these bands (io::Scene holds a mutex: made in place).
std::unique_ptr<io::Scene> scene_of(std::vector<double> wavelengths_nm) {
  auto scene = std::make_unique<io::Scene>();
  scene->wavelengths_nm = std::move(wavelengths_nm);
  return scene;
}

// What a run of `config` on `scene` saves: its record and shapes.
SavedModel saved_by(const RunConfig& config, const io::Scene& scene, int64_t rank) {
  SavedModel saved;
  saved.bands = scene.bands();
  saved.rank = rank;
  saved.sh_degree = config.model.sh_degree;
  if (rank > 0) saved.modules.push_back("colour_model");
  if (config.model.learn_background) saved.modules.push_back("background");
  if (config.wavelength_encoder.enabled) saved.modules.push_back("wavelength_encoder");
  saved.record = model_record(config, scene);
  return saved;
}

std::string refusal(const SavedModel& saved, const RunConfig& config, const io::Scene& scene) {
  return test::error_of(
      [&] { check_resumable(saved, config, scene, "run/checkpoint.pt", "run/config.json"); });
}

const std::string kTail =
    "; a resumed run keeps what shapes its model (start a new run to change it)";

TEST(ModelShape, TheSameSettingsResume) {
  const auto scene_ptr = scene_of({400, 500, 600, 700});
  const io::Scene& scene = *scene_ptr;
  for (const auto& settings : std::vector<std::vector<std::string>>{
           {},
           {"model.spectral_rank=2"},
           {"model.spectral_rank=-1", "model.subspace_from_bands=2"},
           {"wavelength_encoder.enabled=true"},
           {"model.sh_degree=1"}}) {
    const RunConfig config = config_with(settings);
    const int64_t rank = config.model.spectral_rank > 0 ? config.model.spectral_rank : 0;
    EXPECT_EQ(refusal(saved_by(config, scene, rank), config, scene), "(no error)");
  }
  // Settings that shape nothing may change (the iterations, a learning rate).
  const RunConfig config = config_with({"model.spectral_rank=2"});
  EXPECT_EQ(
      refusal(saved_by(config, scene, 2),
              config_with({"model.spectral_rank=2", "iterations=99", "optim.basis_lr=0.1"}), scene),
      "(no error)");
}

TEST(ModelShape, EachSettingThatShapesTheModelIsCheckedByName) {
  const auto scene_ptr = scene_of({400, 500, 600, 700});
  const io::Scene& scene = *scene_ptr;
  const RunConfig rank1 = config_with({"model.spectral_rank=1"});
  const SavedModel saved = saved_by(rank1, scene, 1);
  // The config edited after training: the record names the setting.
  EXPECT_EQ(refusal(saved, config_with({"model.spectral_rank=3"}), scene),
            "run/config.json: model.spectral_rank is 3, but run/checkpoint.pt was trained with 1" +
                kTail);
  EXPECT_EQ(
      refusal(saved, config_with({"model.spectral_rank=1", "model.sh_degree=2"}), scene),
      "run/config.json: model.sh_degree is 2, but run/checkpoint.pt was trained with 3" + kTail);
  EXPECT_EQ(
      refusal(saved, config_with({"model.spectral_rank=1", "model.learn_background=false"}), scene),
      "run/config.json: model.learn_background is false, but run/checkpoint.pt was trained "
      "with a learned background" +
          kTail);
  EXPECT_EQ(
      refusal(saved, config_with({"model.spectral_rank=1", "wavelength_encoder.enabled=true"}),
              scene),
      "run/config.json: wavelength_encoder.enabled is true, but run/checkpoint.pt was trained "
      "with no wavelength encoder" +
          kTail);
  EXPECT_EQ(refusal(saved, config_with({"model.spectral_rank=1", "loss.diffusion=0.3"}), scene),
            "run/config.json: loss.diffusion is 0.3, but run/checkpoint.pt was trained with no "
            "denoiser" +
                kTail);
  // The data now loads other bands.
  EXPECT_EQ(refusal(saved, rank1, *scene_of({400, 500, 600})),
            "run/config.json: the dataset's band count (data.* settings) is 3, but "
            "run/checkpoint.pt was trained with 4" +
                kTail);
  EXPECT_EQ(refusal(saved, rank1, *scene_of({400, 500, 650, 700})),
            "run/config.json: band 2's wavelength (the dataset with data.* settings) is 650 nm, "
            "but run/checkpoint.pt was trained with 600 nm" +
                kTail);
  // A network's width, recorded with the encoder on.
  const RunConfig encoder = config_with({"wavelength_encoder.enabled=true"});
  EXPECT_EQ(
      refusal(saved_by(encoder, scene, 0),
              config_with({"wavelength_encoder.enabled=true", "wavelength_encoder.hidden=32"}),
              scene),
      "run/config.json: wavelength_encoder.hidden is 32, but run/checkpoint.pt was trained "
      "with 64" +
          kTail);
}

TEST(ModelShape, ACheckpointWithoutRecordIsCheckedByItsTensors) {
  const auto scene_ptr = scene_of({400, 500, 600, 700});
  const io::Scene& scene = *scene_ptr;
  const RunConfig rank1 = config_with({"model.spectral_rank=1"});
  SavedModel swapped = saved_by(config_with({"model.spectral_rank=5"}), scene, 5);
  swapped.record = json();  // written before checkpoints had one
  EXPECT_EQ(refusal(swapped, rank1, scene),
            "run/config.json: model.spectral_rank is 1 (1 latent channel), but run/checkpoint.pt "
            "was trained with 5 (5 latent channels)" +
                kTail);
  SavedModel per_band = saved_by(config_with({}), scene, 0);
  per_band.record = json();
  EXPECT_EQ(refusal(per_band, rank1, scene),
            "run/config.json: model.spectral_rank is 1 (1 latent channel), but run/checkpoint.pt "
            "was trained with 0 (one SH set per band)" +
                kTail);
}

}  // namespace
}  // namespace ddhgs::train
