#include "app/block_merge.h"

#include <cmath>
#include <map>
#include <nlohmann/json.hpp>

#include "app/trained_run.h"
#include "core/error.h"
#include "io/blocks/block_grid.h"
#include "io/files/atomic_file.h"
#include "io/files/output_folder.h"
#include "io/rig/rig_layout.h"
#include "io/transforms/transforms.h"
#include "train/run_folder.h"

namespace ddhgs::app {
namespace fs = std::filesystem;
using json = nlohmann::json;

fs::path block_run(const MergeOptions& options, const std::string& name) {
  if (options.runs.empty()) return options.blocks / name / "run";
  std::string path = options.runs;
  for (size_t at = path.find("{block}"); at != std::string::npos;
       at = path.find("{block}", at + name.size()))
    path.replace(at, 7, name);
  return path;
}

namespace {

constexpr double kShC0 = 0.28209479177387814;  // Y_0^0

// The Gaussians of a block's model with a weight above 0 at their centres
// (io::BlockGrid::blend_weight), each opacity times its weight; `faded`
// counts those whose weight is under 1.
io::GaussianPly in_reach(const io::GaussianPly& ply, const io::BlockGrid& grid, int block,
                         double blend, int64_t& faded) {
  const torch::Tensor means = ply.means.to(torch::kFloat64).contiguous();
  const double* p = means.data_ptr<double>();
  std::vector<int64_t> keep;
  std::vector<double> weight;
  for (int64_t g = 0; g < means.size(0); ++g) {
    const core::Vec3 x{p[3 * g], p[3 * g + 1], p[3 * g + 2]};
    const double w = grid.blend_weight(block, grid.frame.along(x), grid.frame.across(x), blend);
    if (w <= 0) continue;
    keep.push_back(g);
    weight.push_back(w);
  }
  const torch::Tensor index = torch::tensor(keep, torch::kInt64);
  io::GaussianPly out = ply;
  for (torch::Tensor* t :
       {&out.means, &out.log_scales, &out.quats, &out.logit_opacities, &out.sh_dc, &out.sh_rest})
    *t = t->index_select(0, index);
  // opacity' = w * opacity, as a logit; weights of 1 leave the value as it was.
  torch::Tensor logits = out.logit_opacities.to(torch::kFloat64).contiguous();
  double* o = logits.data_ptr<double>();
  faded = 0;
  for (size_t i = 0; i < weight.size(); ++i) {
    if (weight[i] >= 1) continue;
    ++faded;
    const double opacity = weight[i] / (1 + std::exp(-o[i]));
    o[i] = std::log(opacity / (1 - opacity));
  }
  if (faded > 0) out.logit_opacities = logits.to(out.logit_opacities.scalar_type());
  return out;
}

void require_same_model(const fs::path& ply, const io::GaussianPly& a, const io::GaussianPly& b) {
  core::require(a.bands() == b.bands() && a.wavelengths_nm == b.wavelengths_nm, ply,
                "has other bands than the first block's model (" + std::to_string(b.bands()) +
                    " against " + std::to_string(a.bands()) +
                    "): blocks of one partition "
                    "must be trained on the same bands");
  core::require(a.sh_rest.size(2) == b.sh_rest.size(2), ply,
                "has another SH degree than the first block's model");
  core::require(a.basis.defined() == b.basis.defined(), ply,
                "is a " + std::string(b.basis.defined() ? "latent" : "per-band") +
                    " colour model but the first block's is not");
}

// Latent models of several blocks as one: their bases side by side and,
// for each block, one more channel holding its mean (a Gaussian's value 1
// there, through its DC coefficient), so that every Gaussian decodes to the
// bands it decoded to in its block: basis . z + alpha mean is sum_i w_i
// (B_b z_i + m_b) with each m_b a column of the joint basis. The joint mean
// is zero.
io::GaussianPly join_latent(const std::vector<io::GaussianPly>& parts) {
  int64_t channels = 0;
  for (const io::GaussianPly& p : parts) channels += p.basis.size(1) + 1;
  const int64_t bands = parts.front().bands(), rest = parts.front().sh_rest.size(2);
  io::GaussianPly out = parts.front();
  out.basis = torch::zeros({bands, channels}, torch::kFloat32);
  out.mean = torch::zeros({bands}, torch::kFloat32);
  std::vector<torch::Tensor> dc, sh_rest;
  int64_t at = 0;
  for (const io::GaussianPly& p : parts) {
    const int64_t k = p.basis.size(1), g = p.sh_dc.size(0);
    out.basis.narrow(1, at, k).copy_(p.basis);
    out.basis.select(1, at + k).copy_(p.mean);
    torch::Tensor d = torch::zeros({g, channels}, torch::kFloat32);
    d.narrow(1, at, k).copy_(p.sh_dc);
    d.select(1, at + k).fill_(float(1 / kShC0));
    torch::Tensor r = torch::zeros({g, channels, rest}, torch::kFloat32);
    r.narrow(1, at, k).copy_(p.sh_rest);
    dc.push_back(d);
    sh_rest.push_back(r);
    at += k + 1;
  }
  out.sh_dc = torch::cat(dc, 0);
  out.sh_rest = torch::cat(sh_rest, 0);
  return out;
}

io::GaussianPly join(const std::vector<io::GaussianPly>& parts) {
  std::vector<torch::Tensor> means, scales, quats, opacities;
  for (const io::GaussianPly& p : parts) {
    means.push_back(p.means);
    scales.push_back(p.log_scales);
    quats.push_back(p.quats);
    opacities.push_back(p.logit_opacities);
  }
  io::GaussianPly out;
  if (parts.front().basis.defined()) {
    out = join_latent(parts);
  } else {
    out = parts.front();
    std::vector<torch::Tensor> dc, rest;
    for (const io::GaussianPly& p : parts) {
      dc.push_back(p.sh_dc);
      rest.push_back(p.sh_rest);
    }
    out.sh_dc = torch::cat(dc, 0);
    out.sh_rest = torch::cat(rest, 0);
  }
  out.means = torch::cat(means, 0);
  out.log_scales = torch::cat(scales, 0);
  out.quats = torch::cat(quats, 0);
  out.logit_opacities = torch::cat(opacities, 0);
  return out;
}

json summary_or_null(const fs::path& path) {
  if (!fs::exists(path)) return nullptr;
  const json j = json::parse(io::read_file(path), nullptr, false);
  return j.is_discarded() ? json(nullptr) : j;
}

}  // namespace

MergeSummary merge_blocks(const MergeOptions& options) {
  const io::BlocksFile file = io::read_blocks_file(options.blocks / "blocks.json");
  std::vector<fs::path> runs;
  std::vector<RunModel> models;
  std::vector<json> configs;
  for (const io::BlockRecord& b : file.blocks) {
    runs.push_back(block_run(options, b.name));
    core::require(fs::is_directory(runs.back()), runs.back(),
                  "no run of " + b.name + " here (train it first, or say where with --runs)");
    models.push_back(open_run_model(runs.back()));
    configs.push_back(train::read_run_config(train::RunPaths{runs.back()}));
    if (models.size() > 1)
      require_same_model(train::RunPaths{runs.back()}.gaussians(), models.front().ply,
                         models.back().ply);
  }
  const io::OutputRequest request{
      options.out, io::OutputKind::Run, options.force, {options.blocks, file.scene}};
  io::check_output_folder(request);

  MergeSummary summary;
  std::vector<io::GaussianPly> parts;
  torch::Tensor background = torch::zeros_like(models.front().background, torch::kFloat64);
  json blocks = json::array();
  double seconds = 0, peak_mib = 0;
  for (size_t b = 0; b < models.size(); ++b) {
    int64_t faded = 0;
    parts.push_back(in_reach(models[b].ply, file.grid, int(b), options.blend, faded));
    summary.trained.push_back(models[b].ply.means.size(0));
    summary.kept.push_back(parts.back().means.size(0));
    summary.faded.push_back(faded);
    summary.gaussians += summary.kept.back();
    background += models[b].background.to(torch::kFloat64) / double(models.size());
    const json s = summary_or_null(train::RunPaths{runs[b]}.summary());
    if (s.is_object()) {
      seconds += s.value("seconds", 0.0);
      peak_mib = std::max(peak_mib, s.value("peak_rss_mib", 0.0));
    }
    blocks.push_back({{"name", file.blocks[b].name},
                      {"run", fs::absolute(runs[b]).lexically_normal().string()},
                      {"gaussians_trained", summary.trained.back()},
                      {"gaussians_kept", summary.kept.back()},
                      {"gaussians_faded", summary.faded.back()},
                      {"train_summary", s}});
  }
  const io::GaussianPly merged = join(parts);

  // The band cameras' corrections: each block's mean, where they learned them.
  std::map<int, io::RigCorrection> corrections;
  std::map<int, int> counts;
  for (const fs::path& run : runs) {
    const fs::path path = train::RunPaths{run}.rig_corrections();
    if (!fs::exists(path)) continue;
    for (const auto& [index, c] : io::read_rig_corrections(path)) {
      io::RigCorrection& sum = corrections[index];
      sum.rotation_rad = sum.rotation_rad + c.rotation_rad;
      sum.offset = sum.offset + c.offset;
      ++counts[index];
    }
  }
  for (auto& [index, c] : corrections) {
    c.rotation_rad = c.rotation_rad * (1.0 / counts[index]);
    c.offset = c.offset * (1.0 / counts[index]);
  }

  json config = configs.front();
  config["data"]["path"] = file.scene.string();
  const train::ModelConfig& model = models.front().config.model;
  io::write_folder_atomically(request, [&](const fs::path& tmp) {
    const train::RunPaths paths{tmp};
    io::write_gaussian_ply(paths.gaussians(), merged);
    io::write_file_atomically(paths.config(), config.dump(2) + "\n");
    if (model.learn_background || model.background_from_views) {
      const torch::Tensor bg = background.to(torch::kFloat32).contiguous();
      const std::vector<float> values(bg.data_ptr<float>(), bg.data_ptr<float>() + bg.numel());
      io::write_file_atomically(paths.learned_background(),
                                json{{"background", values}}.dump(2) + "\n");
    }
    if (!corrections.empty()) {
      const io::TransformsFile scene = io::read_transforms(file.scene / "transforms.json");
      core::require(scene.rig.has_value(), file.scene / "transforms.json",
                    "the blocks learned rig corrections but the scene describes no rig");
      io::write_rig_corrections(paths.rig_corrections(), *scene.rig, corrections);
    }
    const json first = blocks.front()["train_summary"];
    json s = {{"merged_blocks", blocks},
              {"seam_blend", options.blend},
              {"num_gaussians", summary.gaussians},
              {"bands", merged.bands()},
              {"seconds", seconds},
              {"peak_rss_mib", peak_mib}};
    if (first.is_object() && first.contains("iterations")) s["iterations"] = first["iterations"];
    io::write_file_atomically(paths.summary(), s.dump(2) + "\n");
  });
  return summary;
}

}  // namespace ddhgs::app
