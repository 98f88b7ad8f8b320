#include "train/checkpoint.h"

#include "core/error.h"
#include "io/files/atomic_file.h"
#include "io/files/input_file.h"

namespace ddhgs::train {

namespace fs = std::filesystem;

namespace {

std::string group_name(const TrainedModule& module, const std::string& parameter) {
  return module.name + "/" + parameter;
}

}  // namespace

void add_module_groups(model::Adam& adam, const TrainedModule& module) {
  for (const auto& item : module.module->named_parameters())
    adam.add(group_name(module, item.key()), item.value(), module.lr);
}

void scale_module_rate(model::Adam& adam, const TrainedModule& module, double scale) {
  for (const auto& item : module.module->named_parameters())
    adam.group(group_name(module, item.key())).lr = scale * module.lr;
}

void write_archive(const fs::path& path, torch::serialize::OutputArchive& archive) {
  io::write_stream_atomically(path, [&](io::FileSink& sink) {
    archive.save_to([&](const void* data, size_t size) { return sink.write(data, size); });
  });
}

void read_archive(const fs::path& path, torch::serialize::InputArchive& archive,
                  const std::string& unreadable) {
  io::require_regular_file(path);  // LibTorch would wait on a FIFO
  try {
    archive.load_from(path.string());
  } catch (const c10::Error&) {
    throw core::Error(path, unreadable);
  }
}

void save_checkpoint(const fs::path& path, const TrainState& state) {
  torch::serialize::OutputArchive archive;
  const RunCounters& c = state.counters;
  nlohmann::json meta = {{"densify_added", c.densify_added},
                         {"densify_removed", c.densify_removed},
                         {"seconds", c.seconds}};
  if (c.gaussian_seconds >= 0) meta["gaussian_seconds"] = c.gaussian_seconds;
  meta["format_version"] = kCheckpointFormatVersion;
  meta["iteration"] = state.iteration;
  meta["active_sh_degree"] = state.gaussians.active_sh_degree;
  if (!state.model_record.is_null()) meta["model"] = state.model_record;
  archive.write("meta", c10::IValue(meta.dump()));

  torch::serialize::OutputArchive gaussians;
  auto tensors = state.gaussians.values();
  for (size_t i = 0; i < tensors.size(); ++i)
    gaussians.write(model::Gaussians::tensor_names()[i], tensors[i].detach());
  archive.write("gaussians", gaussians);

  torch::serialize::OutputArchive adam;
  state.adam.save(adam);
  archive.write("adam", adam);

  torch::serialize::OutputArchive stats;
  stats.write("grad_sum", state.stats.grad_sum);
  stats.write("count", state.stats.count);
  stats.write("max_radii", state.stats.max_radii);
  archive.write("densify", stats);

  torch::serialize::OutputArchive modules;
  for (const auto& m : state.modules) {
    torch::serialize::OutputArchive sub;
    m.module->save(sub);
    modules.write(m.name, sub);
  }
  archive.write("modules", modules);
  write_archive(path, archive);
}

CheckpointFile open_checkpoint(const fs::path& path) {
  CheckpointFile file;
  file.path = path;
  read_archive(path, file.archive, "not a ddhgs checkpoint (unreadable or truncated)");
  c10::IValue meta_value;
  if (!file.archive.try_read("meta", meta_value) || !meta_value.isString())
    throw core::Error(path, "not a ddhgs checkpoint (no meta record)");
  file.meta = nlohmann::json::parse(meta_value.toStringRef(), nullptr, false);
  const nlohmann::json& meta = file.meta;
  if (!meta.is_object() || !meta.contains("format_version") ||
      !meta["format_version"].is_number_integer())
    throw core::Error(path, "checkpoint meta record is malformed");
  const int version = meta["format_version"].get<int>();
  if (version != kCheckpointFormatVersion)
    throw core::Error(path, "checkpoint format_version " + std::to_string(version) +
                                " is not supported by this ddhgs (reads " +
                                std::to_string(kCheckpointFormatVersion) + ")");
  return file;
}

SavedModel saved_model(CheckpointFile& file) {
  SavedModel saved;
  saved.record = file.meta.value("model", nlohmann::json());
  try {
    torch::serialize::InputArchive gaussians, modules;
    file.archive.read("gaussians", gaussians);
    torch::Tensor sh_dc, sh_rest;
    gaussians.read("sh_dc", sh_dc);
    gaussians.read("sh_rest", sh_rest);
    if (sh_dc.dim() != 2 || sh_rest.dim() != 3)
      throw core::Error(file.path, "checkpoint's SH coefficients are not [G, C] and [G, C, K]");
    const int64_t rest = sh_rest.size(2);
    saved.sh_degree = rest == 0 ? 0 : rest == 3 ? 1 : rest == 8 ? 2 : rest == 15 ? 3 : -1;
    if (saved.sh_degree < 0)
      throw core::Error(file.path, "checkpoint's sh_rest has " + std::to_string(rest) +
                                       " coefficients per channel; expected 0, 3, 8 or 15");
    file.archive.read("modules", modules);
    saved.modules = modules.keys();
    saved.bands = sh_dc.size(1);
    torch::serialize::InputArchive colour;
    if (modules.try_read("colour_model", colour)) {
      torch::Tensor basis;
      colour.read("basis", basis);
      if (basis.dim() != 2)
        throw core::Error(file.path, "checkpoint's colour_model basis is not [N, K]");
      saved.bands = basis.size(0);
      saved.rank = basis.size(1);
    }
  } catch (const c10::Error& e) {
    throw core::Error(file.path,
                      std::string("checkpoint is incomplete (") + e.what_without_backtrace() + ")");
  }
  return saved;
}

void load_checkpoint(const fs::path& path, TrainState& state,
                     const model::AdamOptions& adam_options) {
  CheckpointFile file = open_checkpoint(path);
  load_checkpoint(file, state, adam_options);
}

void load_checkpoint(CheckpointFile& file, TrainState& state,
                     const model::AdamOptions& adam_options) {
  const fs::path& path = file.path;
  torch::serialize::InputArchive& archive = file.archive;
  const nlohmann::json& meta = file.meta;
  try {
    state.iteration = meta.at("iteration").get<int64_t>();
    RunCounters& c = state.counters;
    c.densify_added = meta.at("densify_added").get<int64_t>();
    c.densify_removed = meta.at("densify_removed").get<int64_t>();
    c.seconds = meta.at("seconds").get<double>();
    c.gaussian_seconds = meta.value("gaussian_seconds", -1.0);
    state.gaussians.active_sh_degree = meta.at("active_sh_degree").get<int>();
  } catch (const nlohmann::json::exception&) {
    throw core::Error(path, "checkpoint meta record is malformed");
  }

  try {
    torch::serialize::InputArchive gaussians;
    archive.read("gaussians", gaussians);
    auto tensors = state.gaussians.tensors();
    for (size_t i = 0; i < tensors.size(); ++i) {
      torch::Tensor t;
      gaussians.read(model::Gaussians::tensor_names()[i], t);
      *tensors[i] = t.to(torch::kFloat32).contiguous().requires_grad_(true);
    }
    torch::serialize::InputArchive modules;
    archive.read("modules", modules);
    for (auto& m : state.modules) {
      torch::serialize::InputArchive sub;
      if (!modules.try_read(m.name, sub))
        throw core::Error(path, "checkpoint has no module '" + m.name + "'");
      m.module->load(sub);
    }

    // Module parameters are registered after loading them, so the optimizer
    // holds the loaded tensors.
    state.adam = model::Adam(adam_options);
    for (size_t i = 0; i < tensors.size(); ++i)
      state.adam.add(model::Gaussians::tensor_names()[i], *tensors[i], 0.0);
    for (const auto& m : state.modules) add_module_groups(state.adam, m);
    torch::serialize::InputArchive adam;
    archive.read("adam", adam);
    state.adam.load(adam, path.string());

    torch::serialize::InputArchive stats;
    archive.read("densify", stats);
    stats.read("grad_sum", state.stats.grad_sum);
    stats.read("count", state.stats.count);
    stats.read("max_radii", state.stats.max_radii);

  } catch (const c10::Error& e) {
    throw core::Error(path,
                      std::string("checkpoint is incomplete (") + e.what_without_backtrace() + ")");
  }
  const int64_t g = state.gaussians.size();
  if (state.stats.grad_sum.size(0) != g || state.gaussians.sh_rest.size(0) != g)
    throw core::Error(path, "checkpoint tensors disagree on the number of Gaussians");
}

}  // namespace ddhgs::train
