#include "eval/evaluate.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "core/error.h"
#include "core/log.h"
#include "core/tensor_values.h"
#include "core/text.h"
#include "io/files/atomic_file.h"
#include "io/scene/backdrop.h"

namespace ddhgs::eval {
namespace {

using json = nlohmann::json;

// A spectral angle, or null where there is none (a one-band view).
json angle_json(double sam_rad) {
  return std::isnan(sam_rad) ? json() : json(sam_rad);
}

json metrics_json(const ImageMetrics& m, const std::vector<double>& wavelengths_nm) {
  return {{"psnr", m.psnr_db},
          {"ssim", m.ssim},
          {"sam", angle_json(m.sam_rad)},
          {"rmse", m.rmse},
          {"per_band_psnr", {{"wavelengths_nm", wavelengths_nm}, {"psnr", m.band_psnr_db}}}};
}

// The views (rows against the stored views) without a spectral angle: those
// that hold one band, whose "spectrum" is one value.
int views_without_angle(const EvalReport& report) {
  int count = 0;
  for (const ViewResult& r : report.per_view)
    count += r.truth == "views" && std::isnan(r.metrics.sam_rad);
  return count;
}

// Why SAM is "-" or null, or "" when every view has an angle.
std::string angle_note(const EvalReport& report) {
  const int without = views_without_angle(report);
  if (without == 0) return "";
  const int views = int(report.per_view.size() / (report.mean_clean ? 2 : 1));
  if (without == views)
    return "SAM -: every view holds one band, and one band has no spectral angle (it needs two "
           "or more)";
  return "SAM over the " + std::to_string(views - without) + " of " + std::to_string(views) +
         " views that hold two or more bands; a one-band view has no spectral angle";
}

// Mean over views; the interior over the views that have one.
std::optional<ObjectMetrics> mean_object(const std::vector<ObjectMetrics>& views) {
  if (views.empty()) return std::nullopt;
  std::vector<RegionMetrics> object, interior;
  ObjectMetrics mean;
  for (const ObjectMetrics& v : views) {
    object.push_back(v.object);
    if (v.interior) interior.push_back(*v.interior);
    mean.share += v.share / double(views.size());
  }
  mean.object = mean_region_metrics(object);
  if (!interior.empty()) mean.interior = mean_region_metrics(interior);
  return mean;
}

json object_json(const ObjectMetrics& m) {
  json j = {
      {"pixel_share", m.share}, {"psnr", m.object.psnr_db}, {"sam", angle_json(m.object.sam_rad)}};
  if (m.interior) {
    j["interior_psnr"] = m.interior->psnr_db;
    j["interior_sam"] = angle_json(m.interior->sam_rad);
  }
  return j;
}

struct AlignmentSummary {
  int moved = 0, views = 0;
  double motion_px = 0;  // mean over the views
};

AlignmentSummary summarise_alignment(const EvalReport& report) {
  AlignmentSummary s;
  for (const ViewResult& r : report.per_view) {
    if (!r.aligned) continue;
    ++s.views;
    s.moved += r.aligned->moved;
    s.motion_px += r.aligned->motion_px;
  }
  if (s.views > 0) s.motion_px /= s.views;
  return s;
}

}  // namespace

torch::Tensor render_view(const io::Scene& scene, const model::Gaussians& gaussians,
                          const torch::Tensor& background, int view,
                          const torch::Tensor& band_offsets) {
  torch::NoGradGuard no_grad;
  return model::render_gaussians(gaussians, scene.views[size_t(view)].camera, background,
                                 band_offsets)
      .image;
}

ViewMetrics measure_view(const io::Scene& scene, int view, const torch::Tensor& image,
                         const torch::Tensor& backdrop) {
  torch::NoGradGuard no_grad;
  // A view of a band-per-view scene is measured on the bands it holds.
  const torch::Tensor measured = scene.view_slice(view, image.detach().clamp(0, 1));
  const torch::Tensor own_backdrop =
      backdrop.defined() ? scene.view_slice(view, backdrop) : backdrop;
  const std::vector<int>& bands = scene.views[size_t(view)].bands;
  // One band has no spectrum, so no spectral angle (it would be 0 always).
  const bool one_band = measured.size(2) < 2;
  auto measure = [&](const torch::Tensor& truth) {
    ImageMetrics image_metrics =
        on_scene_bands(compute_metrics(measured, truth), bands, scene.bands());
    if (one_band) image_metrics.sam_rad = std::nan("");
    return image_metrics;
  };
  auto measure_region = [&](const torch::Tensor& truth) {
    std::optional<ObjectMetrics> object = measure_object(measured, truth, own_backdrop);
    if (object && one_band) {
      object->object.sam_rad = std::nan("");
      if (object->interior) object->interior->sam_rad = std::nan("");
    }
    return object;
  };
  ViewMetrics m;
  const torch::Tensor stored = scene.image(view);
  m.stored = measure(stored);
  if (backdrop.defined()) m.stored_object = measure_region(stored);
  const torch::Tensor clean = scene.clean_image(view);
  if (clean.defined()) {
    m.clean = measure(clean);
    if (backdrop.defined()) m.clean_object = measure_region(clean);
  }
  return m;
}

std::optional<ObjectMetrics> measure_object(const torch::Tensor& image, const torch::Tensor& truth,
                                            const torch::Tensor& backdrop) {
  torch::NoGradGuard no_grad;
  const torch::Tensor mask = io::object_mask(truth, backdrop);
  const torch::Tensor measured = image.detach().clamp(0, 1);
  const std::optional<RegionMetrics> object = region_metrics(measured, truth, mask);
  if (!object) return std::nullopt;
  ObjectMetrics m;
  m.object = *object;
  m.interior = region_metrics(measured, truth, io::interior(mask));
  m.share = mask.to(torch::kFloat64).mean().item<double>();
  return m;
}

std::vector<int> split_views(const io::Scene& scene, const std::string& split) {
  if (split == "test") return scene.test;
  if (split == "train") return scene.train;
  if (split == "all") {
    std::vector<int> all(scene.views.size());
    for (size_t i = 0; i < all.size(); ++i) all[i] = int(i);
    return all;
  }
  throw core::Error("--split: expected test, train or all, got " + core::quoted_value(split));
}

Timing time_renders(const io::Scene& scene, const model::Gaussians& gaussians,
                    const torch::Tensor& background, const std::vector<int>& views, int repeats) {
  torch::NoGradGuard no_grad;
  Timing timing;
  timing.repeats = repeats;
  timing.views = int(views.size());
  if (views.empty() || repeats <= 0) return timing;
  // The first pass pays for allocator growth and cold caches.
  for (int v : views) render_view(scene, gaussians, background, v);
  std::vector<double> per_frame_ms;
  for (int r = 0; r < repeats; ++r) {
    auto start = std::chrono::steady_clock::now();
    for (int v : views) render_view(scene, gaussians, background, v);
    std::chrono::duration<double, std::milli> elapsed = std::chrono::steady_clock::now() - start;
    per_frame_ms.push_back(elapsed.count() / double(views.size()));
  }
  std::sort(per_frame_ms.begin(), per_frame_ms.end());
  size_t n = per_frame_ms.size();
  timing.median_ms =
      n % 2 ? per_frame_ms[n / 2] : 0.5 * (per_frame_ms[n / 2 - 1] + per_frame_ms[n / 2]);
  return timing;
}

EvalReport evaluate(const io::Scene& scene, const model::Gaussians& gaussians,
                    const torch::Tensor& background, const std::vector<int>& views,
                    const std::string& split_name, const EvalOptions& options) {
  core::require(gaussians.bands() == scene.bands(), scene.root,
                "the model has " + std::to_string(gaussians.bands()) +
                    " bands but the dataset loads " + std::to_string(scene.bands()) +
                    " (band range or binning differs from training?)");
  core::require(!views.empty(), scene.root,
                "the " + split_name + " split has no views (try --split train or all)");
  torch::NoGradGuard no_grad;
  EvalReport report;
  report.split = split_name;
  report.wavelengths_nm = scene.wavelengths_nm;
  report.gaussians = gaussians.size();
  report.width = scene.views[size_t(views.front())].camera.intrinsics.width;
  report.height = scene.views[size_t(views.front())].camera.intrinsics.height;

  report.backdrop = options.backdrop;
  report.align = options.align;
  std::vector<ImageMetrics> stored, clean, aligned;
  std::vector<ObjectMetrics> stored_object, clean_object;
  core::ProgressBar bar("eval " + split_name + (options.align ? " (aligning poses)" : ""),
                        int64_t(views.size()));
  for (size_t i = 0; i < views.size(); ++i) {
    int v = views[i];
    const std::string& name = scene.views[size_t(v)].name;
    const ViewMetrics m =
        measure_view(scene, v, render_view(scene, gaussians, background, v), options.backdrop);
    stored.push_back(m.stored);
    report.per_view.push_back({name, "views", m.stored, m.stored_object, std::nullopt});
    if (options.align) {
      const torch::Tensor truth = scene.image(v);
      const AlignedView a =
          align_view(gaussians, scene.views[size_t(v)].camera, background, truth, *options.align);
      AlignedMetrics am{compute_metrics(a.image.detach().clamp(0, 1), truth), a.moved, a.motion_px};
      aligned.push_back(am.metrics);
      report.per_view.back().aligned = am;
    }
    if (m.stored_object) stored_object.push_back(*m.stored_object);
    if (m.clean) {
      clean.push_back(*m.clean);
      report.per_view.push_back({name, "clean", *m.clean, m.clean_object, std::nullopt});
      if (m.clean_object) clean_object.push_back(*m.clean_object);
    }
    bar.update(
        int64_t(i + 1),
        "PSNR " + core::fixed(stored.back().psnr_db, 2) + " dB" +
            (options.align ? ", aligned " + core::fixed(aligned.back().psnr_db, 2) + " dB" : ""));
  }
  report.mean = mean_metrics(stored);
  if (!clean.empty()) report.mean_clean = mean_metrics(clean);
  report.mean_object = mean_object(stored_object);
  report.mean_object_clean = mean_object(clean_object);
  if (!aligned.empty()) report.mean_aligned = mean_metrics(aligned);
  bar.finish("PSNR " + core::fixed(report.mean.psnr_db, 2) + " dB");

  if (options.fps_repeats > 0) {
    const std::vector<int>& timed = scene.test.empty() ? views : scene.test;
    report.timing = time_renders(scene, gaussians, background, timed, options.fps_repeats);
  }
  return report;
}

void write_metrics_json(const std::filesystem::path& path, const EvalReport& report) {
  json j = metrics_json(report.mean, report.wavelengths_nm);
  j["split"] = report.split;
  j["views"] = int(report.per_view.size() / (report.mean_clean ? 2 : 1));
  j["gaussians"] = report.gaussians;
  j["bands"] = report.wavelengths_nm.size();
  j["width"] = report.width;
  j["height"] = report.height;
  j["units"] = {{"psnr", "dB, capped at " + core::fixed(kMaxPsnrDb, 0)},
                {"sam", "radians"},
                {"ssim", "11x11 Gaussian window, sigma 1.5, valid windows"},
                {"fps", "frames per second, render only"}};
  if (report.mean_clean) j["clean"] = metrics_json(*report.mean_clean, report.wavelengths_nm);
  if (const std::string note = angle_note(report); !note.empty()) j["notes"]["sam"] = note;
  if (report.backdrop.defined()) {
    j["backdrop"] = {{"value", core::to_doubles(report.backdrop)},
                     {"tolerance", io::kBackdropTolerance}};
    j["units"]["object"] =
        "pixels of the truth that differ from the backdrop by more than its tolerance in some "
        "band; interior: those without a backdrop pixel among their 8 neighbours";
  }
  if (report.mean_aligned && report.align) {
    json a = metrics_json(*report.mean_aligned, report.wavelengths_nm);
    const AlignmentSummary s = summarise_alignment(report);
    a["steps"] = report.align->steps;
    a["step_px"] = report.align->step_px;
    a["moved_views"] = s.moved;
    a["mean_motion_px"] = s.motion_px;
    j["aligned"] = a;
    j["units"]["aligned"] =
        "each view measured again from its pose aligned to the stored view with the Gaussians "
        "frozen (a rotation about the camera centre and a shift); motion_px: the mean image "
        "displacement of the Gaussians in the frame that the alignment makes";
  }
  if (report.mean_object) j["object"] = object_json(*report.mean_object);
  if (report.mean_object_clean) j["clean"]["object"] = object_json(*report.mean_object_clean);
  if (report.timing && report.timing->repeats > 0) {
    j["fps"] = report.timing->fps();
    j["render_ms"] = report.timing->median_ms;
    j["fps_repeats"] = report.timing->repeats;
    j["fps_views"] = report.timing->views;
  }
  io::write_file_atomically(path, j.dump(2) + "\n");
}

void write_per_view_csv(const std::filesystem::path& path, const EvalReport& report) {
  // A masked scene's object columns follow; empty where a view has no
  // object (or no interior).
  const bool masked = report.backdrop.defined();
  std::ostringstream csv;
  csv << "view,truth,psnr_db,ssim,sam_rad,rmse";
  if (masked)
    csv << ",object_share,object_psnr_db,object_sam_rad,interior_psnr_db,interior_sam_rad";
  // Then, with --align-poses, the aligned figures (empty on clean rows).
  const bool aligned = report.mean_aligned.has_value();
  if (aligned)
    csv << ",aligned_psnr_db,aligned_ssim,aligned_sam_rad,aligned_rmse,aligned_motion_px";
  csv << "\n";
  // A one-band view's spectral angle is empty too.
  auto angle = [](double sam_rad) { return std::isnan(sam_rad) ? "" : core::fixed(sam_rad, 8); };
  for (const ViewResult& r : report.per_view) {
    csv << r.view << "," << r.truth << "," << core::fixed(r.metrics.psnr_db, 6) << ","
        << core::fixed(r.metrics.ssim, 8) << "," << angle(r.metrics.sam_rad) << ","
        << core::fixed(r.metrics.rmse, 8);
    if (masked) {
      const std::optional<ObjectMetrics>& o = r.object;
      const RegionMetrics* in = o && o->interior ? &*o->interior : nullptr;
      csv << "," << (o ? core::fixed(o->share, 6) : "") << ","
          << (o ? core::fixed(o->object.psnr_db, 6) : "") << ","
          << (o ? angle(o->object.sam_rad) : "") << "," << (in ? core::fixed(in->psnr_db, 6) : "")
          << "," << (in ? angle(in->sam_rad) : "");
    }
    if (aligned) {
      if (const auto& a = r.aligned)
        csv << "," << core::fixed(a->metrics.psnr_db, 6) << "," << core::fixed(a->metrics.ssim, 8)
            << "," << core::fixed(a->metrics.sam_rad, 8) << "," << core::fixed(a->metrics.rmse, 8)
            << "," << core::fixed(a->motion_px, 4);
      else
        csv << ",,,,,";
    }
    csv << "\n";
  }
  io::write_file_atomically(path, csv.str());
}

std::string format_report(const EvalReport& report) {
  std::ostringstream out;
  size_t views = report.per_view.size() / (report.mean_clean ? 2 : 1);
  out << report.split << " split: " << views << (views == 1 ? " view, " : " views, ")
      << report.width << "x" << report.height << " px, " << report.wavelengths_nm.size()
      << " bands, " << report.gaussians << " Gaussians\n";
  out << "  truth    PSNR dB     SSIM  SAM rad     RMSE\n";
  // A spectral angle as the table shows it: "-" where there is none.
  auto angle = [](double sam_rad) { return std::isnan(sam_rad) ? "-" : core::fixed(sam_rad, 4); };
  auto row = [&](const char* name, const ImageMetrics& m) {
    char buf[128];
    std::snprintf(buf, sizeof buf, "  %-7s %8.3f %8.4f %8s %8.5f\n", name, m.psnr_db, m.ssim,
                  angle(m.sam_rad).c_str(), m.rmse);
    out << buf;
  };
  // Under the row of their truth, indented.
  auto object_rows = [&](const ObjectMetrics& m) {
    char buf[160];
    std::snprintf(buf, sizeof buf,
                  "   %-6s %8.3f %8s %8s %8s  (%.0f %% of the pixels: unlike the backdrop)\n",
                  "object", m.object.psnr_db, "-", angle(m.object.sam_rad).c_str(), "-",
                  100 * m.share);
    out << buf;
    if (!m.interior) return;
    std::snprintf(buf, sizeof buf,
                  "   %-6s %8.3f %8s %8s %8s  (the object less its 1-pixel outline)\n", "inside",
                  m.interior->psnr_db, "-", angle(m.interior->sam_rad).c_str(), "-");
    out << buf;
  };
  row("views", report.mean);
  if (report.mean_object) object_rows(*report.mean_object);
  if (report.mean_aligned) {
    row("aligned", *report.mean_aligned);
    const AlignmentSummary s = summarise_alignment(report);
    char buf[200];
    std::snprintf(buf, sizeof buf,
                  "          (poses aligned to the views: %d of %d moved, the image by %.2f px "
                  "on average)\n",
                  s.moved, s.views, s.motion_px);
    out << buf;
  }
  if (report.mean_clean) row("clean", *report.mean_clean);
  if (report.mean_object_clean) object_rows(*report.mean_object_clean);
  if (const std::string note = angle_note(report); !note.empty()) out << "  (" << note << ")\n";
  if (report.timing && report.timing->repeats > 0)
    out << "  render " << core::fixed(report.timing->fps(), 2) << " FPS ("
        << core::fixed(report.timing->median_ms, 1) << " ms per frame, median of "
        << report.timing->repeats << " passes over " << report.timing->views << " views)\n";
  return out.str();
}

}  // namespace ddhgs::eval
