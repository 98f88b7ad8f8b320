#include "train/checkpoint.h"

#include "core/error.h"
#include "io/files/atomic_file.h"

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

void load_checkpoint(const fs::path& path, TrainState& state,
                     const model::AdamOptions& adam_options) {
  if (!fs::exists(path)) throw core::Error(path, "no such checkpoint");
  torch::serialize::InputArchive archive;
  read_archive(path, archive, "not a ddhgs checkpoint (unreadable or truncated)");
  c10::IValue meta_value;
  if (!archive.try_read("meta", meta_value) || !meta_value.isString())
    throw core::Error(path, "not a ddhgs checkpoint (no meta record)");
  nlohmann::json meta = nlohmann::json::parse(meta_value.toStringRef(), nullptr, false);
  if (!meta.is_object() || !meta.contains("format_version"))
    throw core::Error(path, "checkpoint meta record is malformed");
  const int version = meta["format_version"].get<int>();
  if (version != kCheckpointFormatVersion)
    throw core::Error(path, "checkpoint format_version " + std::to_string(version) +
                                " is not supported by this ddhgs (reads " +
                                std::to_string(kCheckpointFormatVersion) + ")");
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
