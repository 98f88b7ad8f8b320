#include "train/model_shape.h"

#include <algorithm>

#include "core/error.h"
#include "core/log.h"

namespace ddhgs::train {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// A recorded setting, compared only while `when` holds for the config
// (a network's width matters only when the network is there).
struct RecordedSetting {
  const char* key;
  bool (*when)(const RunConfig& config);
};

bool always(const RunConfig&) {
  return true;
}
bool rank_from_scene(const RunConfig& config) {
  return config.model.spectral_rank < 0;
}
bool encoder_on(const RunConfig& config) {
  return config.wavelength_encoder.enabled;
}
bool denoiser_on(const RunConfig& config) {
  return config.diffusion.enabled();
}

const RecordedSetting kRecorded[] = {
    {"model.spectral_rank", always},
    {"model.subspace_from_bands", rank_from_scene},
    {"wavelength_encoder.frequencies", encoder_on},
    {"wavelength_encoder.include_input", encoder_on},
    {"wavelength_encoder.hidden", encoder_on},
    {"wavelength_encoder.layers", encoder_on},
    {"diffusion.base_channels", denoiser_on},
    {"diffusion.channel_multipliers", denoiser_on},
    {"diffusion.blocks_per_level", denoiser_on},
    {"diffusion.attention", denoiser_on},
};

json::json_pointer pointer(const std::string& key) {
  std::string path = "/" + key;
  std::replace(path.begin(), path.end(), '.', '/');
  return json::json_pointer(path);
}

std::string rank_text(int64_t rank) {
  if (rank == 0) return "0 (one SH set per band)";
  return std::to_string(rank) + " (" + std::to_string(rank) + " latent channel" +
         (rank == 1 ? ")" : "s)");
}

// The refusal: the setting, the config's value and what the checkpoint holds.
[[noreturn]] void refuse(const fs::path& config_file, const std::string& setting,
                         const std::string& value, const fs::path& checkpoint,
                         const std::string& saved) {
  throw core::Error(config_file,
                    setting + " is " + value + ", but " + checkpoint.string() +
                        " was trained with " + saved +
                        "; a resumed run keeps what shapes its model (start a new run to change "
                        "it)");
}

void check_record(const json& record, const RunConfig& config, const fs::path& checkpoint,
                  const fs::path& config_file) {
  const json* settings =
      record.is_object() && record.contains("settings") ? &record["settings"] : nullptr;
  if (!settings || !settings->is_object()) return;
  for (const RecordedSetting& s : kRecorded) {
    if (!s.when(config) || !settings->contains(s.key)) continue;
    const json& saved = settings->at(s.key);
    const json& value = config.resolved.value(pointer(s.key), json());
    if (saved != value) refuse(config_file, s.key, value.dump(), checkpoint, saved.dump());
  }
}

void check_bands(const SavedModel& saved, const json& record, const io::Scene& scene,
                 const fs::path& checkpoint, const fs::path& config_file) {
  const std::string setting = "the dataset's band count (data.* settings)";
  if (scene.bands() != saved.bands)
    refuse(config_file, setting, std::to_string(scene.bands()), checkpoint,
           std::to_string(saved.bands));
  if (!record.is_object() || !record.contains("wavelengths_nm")) return;
  const std::vector<double> trained = record["wavelengths_nm"].get<std::vector<double>>();
  if (trained.size() != scene.wavelengths_nm.size()) return;  // the count said it
  for (size_t b = 0; b < trained.size(); ++b)
    if (trained[b] != scene.wavelengths_nm[b])
      refuse(config_file,
             "band " + std::to_string(b) + "'s wavelength (the dataset with data.* settings)",
             core::format_g(scene.wavelengths_nm[b]) + " nm", checkpoint,
             core::format_g(trained[b]) + " nm");
}

// A module trained beside the Gaussians: on in the config, present in the checkpoint.
void check_module(const SavedModel& saved, const std::string& module, bool on,
                  const std::string& setting, const std::string& value, const std::string& what,
                  const fs::path& checkpoint, const fs::path& config_file) {
  const bool held =
      std::find(saved.modules.begin(), saved.modules.end(), module) != saved.modules.end();
  if (on != held) refuse(config_file, setting, value, checkpoint, (held ? "a " : "no ") + what);
}

}  // namespace

json model_record(const RunConfig& config, const io::Scene& scene) {
  json settings = json::object();
  for (const RecordedSetting& s : kRecorded)
    settings[s.key] = config.resolved.value(pointer(s.key), json());
  return {{"settings", settings}, {"wavelengths_nm", scene.wavelengths_nm}};
}

void check_resumable(const SavedModel& saved, const RunConfig& config, const io::Scene& scene,
                     const fs::path& checkpoint, const fs::path& config_file) {
  check_record(saved.record, config, checkpoint, config_file);
  const ModelConfig& model = config.model;
  if (model.sh_degree != saved.sh_degree)
    refuse(config_file, "model.sh_degree", std::to_string(model.sh_degree), checkpoint,
           std::to_string(saved.sh_degree));
  check_bands(saved, saved.record, scene, checkpoint, config_file);
  // A rank taken from the scene (-1) is checked by the record: the same
  // setting on the same bands finds the same rank.
  if (model.spectral_rank >= 0 && model.spectral_rank != saved.rank)
    refuse(config_file, "model.spectral_rank", rank_text(model.spectral_rank), checkpoint,
           rank_text(saved.rank));
  const auto on_off = [](bool on) { return std::string(on ? "true" : "false"); };
  check_module(saved, "wavelength_encoder", config.wavelength_encoder.enabled,
               "wavelength_encoder.enabled", on_off(config.wavelength_encoder.enabled),
               "wavelength encoder", checkpoint, config_file);
  check_module(saved, "background", model.learn_background, "model.learn_background",
               on_off(model.learn_background), "learned background", checkpoint, config_file);
  check_module(saved, "camera_refinement", config.camera_refinement.enabled,
               "camera_refinement.enabled", on_off(config.camera_refinement.enabled),
               "camera refinement", checkpoint, config_file);
  check_module(saved, "denoiser", config.diffusion.enabled(), "loss.diffusion",
               core::format_g(config.diffusion.weight), "denoiser", checkpoint, config_file);
}

}  // namespace ddhgs::train
