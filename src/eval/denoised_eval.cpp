#include "eval/denoised_eval.h"

#include <chrono>
#include <cstdio>
#include <sstream>

#include "core/error.h"
#include "core/log.h"
#include "core/text.h"
#include "eval/evaluate.h"
#include "io/files/atomic_file.h"

namespace ddhgs::eval {
namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

json metrics_summary(const ImageMetrics& m) {
  return {{"psnr", m.psnr_db}, {"ssim", m.ssim}, {"sam", m.sam_rad}, {"rmse", m.rmse}};
}

}  // namespace

std::vector<DenoiseSetting> denoise_settings(const std::vector<int64_t>& ddim_steps, bool ddpm,
                                             const model::SamplerOptions& base) {
  // "ddim10", or "ddim10-mean8" for the mean of 8 samples.
  const std::string mean =
      base.samples > 1 ? "-mean" + std::to_string(base.samples) : std::string();
  std::vector<DenoiseSetting> settings;
  for (int64_t k : ddim_steps) {
    model::SamplerOptions s = base;
    s.method = model::SamplerMethod::Ddim;
    s.steps = k;
    settings.push_back({"ddim" + std::to_string(k) + mean, s});
  }
  if (ddpm) {
    model::SamplerOptions s = base;
    s.method = model::SamplerMethod::Ddpm;
    settings.push_back({"ddpm" + mean, s});
  }
  return settings;
}

DenoisedReport evaluate_denoised(const io::Scene& scene, const model::Gaussians& gaussians,
                                 const torch::Tensor& background, model::Denoiser& denoiser,
                                 const std::vector<int>& views, const std::string& split_name,
                                 const std::vector<DenoiseSetting>& settings) {
  core::require(!views.empty(), scene.root, "the " + split_name + " split has no views");
  for (const auto& s : settings) s.sampler.validate(denoiser.schedule.steps, "denoiser " + s.name);
  torch::NoGradGuard no_grad;
  DenoisedReport report;
  report.split = split_name;
  report.views = int(views.size());
  report.results.resize(settings.size());
  std::vector<std::vector<ImageMetrics>> stored(settings.size()), clean(settings.size());
  double render_ms = 0;
  core::ProgressBar bar("denoise " + split_name, int64_t(views.size() * settings.size()));
  for (size_t i = 0; i < views.size(); ++i) {
    const int v = views[i];
    const std::string& name = scene.views[size_t(v)].name;
    auto start = Clock::now();
    torch::Tensor render = render_view(scene, gaussians, background, v);
    render_ms += ms_since(start);
    // The first sampler call pays for allocator growth and cold caches.
    if (i == 0 && !settings.empty())
      model::denoise_view(denoiser, render, settings.front().sampler);
    for (size_t s = 0; s < settings.size(); ++s) {
      DenoisedResult& result = report.results[s];
      start = Clock::now();
      torch::Tensor denoised = model::denoise_view(denoiser, render, settings[s].sampler);
      result.denoise_ms += ms_since(start);
      const ViewMetrics m = measure_view(scene, v, denoised);
      stored[s].push_back(m.stored);
      result.per_view.push_back({name, "views", m.stored, std::nullopt, std::nullopt});
      if (m.clean) {
        clean[s].push_back(*m.clean);
        result.per_view.push_back({name, "clean", *m.clean, std::nullopt, std::nullopt});
      }
      bar.update(int64_t(i * settings.size() + s + 1),
                 settings[s].name + " PSNR " + core::fixed(stored[s].back().psnr_db, 2) + " dB");
    }
  }
  report.render_ms = render_ms / double(views.size());
  for (size_t s = 0; s < settings.size(); ++s) {
    DenoisedResult& result = report.results[s];
    result.setting = settings[s];
    result.denoise_ms /= double(views.size());
    result.mean = mean_metrics(stored[s]);
    if (!clean[s].empty()) result.mean_clean = mean_metrics(clean[s]);
  }
  bar.finish();
  return report;
}

json denoised_json(const DenoisedReport& report) {
  json settings = json::array();
  for (const DenoisedResult& r : report.results) {
    const model::SamplerOptions& s = r.setting.sampler;
    json j = metrics_summary(r.mean);
    j["name"] = r.setting.name;
    j["method"] = s.method == model::SamplerMethod::Ddim ? "ddim" : "ddpm";
    if (s.method == model::SamplerMethod::Ddim) {
      j["steps"] = s.steps;
      j["eta"] = s.eta;
    }
    j["start_strength"] = s.start_strength;
    j["seed"] = s.seed;
    j["samples"] = s.samples;
    if (r.mean_clean) j["clean"] = metrics_summary(*r.mean_clean);
    j["denoise_ms"] = r.denoise_ms;
    j["fps"] = report.fps(r);
    settings.push_back(j);
  }
  return {{"split", report.split},
          {"views", report.views},
          {"render_ms", report.render_ms},
          {"units",
           {{"psnr", "dB"},
            {"sam", "radians"},
            {"fps", "frames per second, render + denoise, one pass over the views"}}},
          {"settings", settings}};
}

void write_denoised_json(const std::filesystem::path& path, const DenoisedReport& report) {
  io::write_file_atomically(path, denoised_json(report).dump(2) + "\n");
}

void write_denoised_csv(const std::filesystem::path& path, const DenoisedReport& report) {
  std::ostringstream csv;
  csv << "setting,view,truth,psnr_db,ssim,sam_rad,rmse\n";
  for (const DenoisedResult& result : report.results)
    for (const ViewResult& r : result.per_view)
      csv << result.setting.name << "," << r.view << "," << r.truth << ","
          << core::fixed(r.metrics.psnr_db, 6) << "," << core::fixed(r.metrics.ssim, 8) << ","
          << core::fixed(r.metrics.sam_rad, 8) << "," << core::fixed(r.metrics.rmse, 8) << "\n";
  io::write_file_atomically(path, csv.str());
}

std::string format_denoised(const DenoisedReport& report) {
  std::ostringstream out;
  out << "denoised (" << report.views << (report.views == 1 ? " view" : " views") << ", render "
      << core::fixed(report.render_ms, 1) << " ms per frame)\n";
  out << "  setting  truth    PSNR dB     SSIM  SAM rad     RMSE      FPS\n";
  for (const DenoisedResult& r : report.results) {
    auto row = [&](const char* truth, const ImageMetrics& m) {
      char buf[160];
      std::snprintf(buf, sizeof buf, "  %-8s %-7s %8.3f %8.4f %8.4f %8.5f %8.2f\n",
                    r.setting.name.c_str(), truth, m.psnr_db, m.ssim, m.sam_rad, m.rmse,
                    report.fps(r));
      out << buf;
    };
    row("views", r.mean);
    if (r.mean_clean) row("clean", *r.mean_clean);
  }
  return out.str();
}

}  // namespace ddhgs::eval
