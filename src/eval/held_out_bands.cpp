#include "eval/held_out_bands.h"

#include <cmath>
#include <cstdio>

#include "core/band_map.h"
#include "core/error.h"
#include "core/log.h"
#include "eval/metrics.h"

namespace ddhgs::eval {
namespace {

double mean_where(const std::vector<double>& v, const std::vector<bool>& mask, bool value) {
  double sum = 0;
  int count = 0;
  for (size_t i = 0; i < v.size(); ++i)
    if (mask[i] == value) sum += v[i], ++count;
  return count > 0 ? sum / count : std::nan("");
}

}  // namespace

double HeldOutBands::trained_mean_db() const {
  return mean_where(psnr_db, held_out, false);
}

double HeldOutBands::held_out_mean_db() const {
  return mean_where(psnr_db, held_out, true);
}

HeldOutBands evaluate_held_out_bands(const io::Scene& all_bands, const model::Gaussians& gaussians,
                                     const std::vector<double>& trained_nm,
                                     const torch::Tensor& background,
                                     const std::vector<int>& views) {
  core::require(!views.empty(), all_bands.root, "no views to measure held-out bands on");
  HeldOutBands r;
  r.clean = all_bands.has_clean();
  r.views = int(views.size());
  std::vector<int64_t> measured;
  const double lo = trained_nm.front(), hi = trained_nm.back();
  for (size_t b = 0; b < all_bands.wavelengths_nm.size(); ++b) {
    const double w = all_bands.wavelengths_nm[b];
    bool trained = false;
    for (double t : trained_nm) trained = trained || std::abs(t - w) < 1e-6;
    if (!trained && (w < lo || w > hi)) {
      r.skipped_nm.push_back(w);
      continue;
    }
    measured.push_back(int64_t(b));
    r.wavelengths_nm.push_back(w);
    r.held_out.push_back(!trained);
  }
  core::require(int64_t(r.wavelengths_nm.size()) > int64_t(trained_nm.size()), all_bands.root,
                "the dataset has no bands between the model's that it was not trained on");
  model::Gaussians mapped = gaussians;
  mapped.colour = gaussians.colour.mapped(core::interpolation_map(trained_nm, r.wavelengths_nm));
  const torch::Tensor index = torch::tensor(measured);
  torch::NoGradGuard no_grad;
  r.psnr_db.assign(measured.size(), 0.0);
  core::ProgressBar bar("held-out bands", int64_t(views.size()));
  for (size_t i = 0; i < views.size(); ++i) {
    const int v = views[i];
    const core::Camera& camera = all_bands.views[size_t(v)].camera;
    const torch::Tensor image =
        model::render_gaussians(mapped, camera, background).image.clamp(0, 1);
    const torch::Tensor truth =
        (r.clean ? all_bands.clean_image(v) : all_bands.image(v)).index_select(2, index);
    const std::vector<double> bands = band_psnr_db(image, truth);
    for (size_t b = 0; b < bands.size(); ++b) r.psnr_db[b] += bands[b] / double(views.size());
    bar.update(int64_t(i + 1));
  }
  bar.finish();
  return r;
}

nlohmann::json to_json(const HeldOutBands& r) {
  nlohmann::json bands = nlohmann::json::array();
  for (size_t b = 0; b < r.psnr_db.size(); ++b)
    bands.push_back({{"wavelength_nm", r.wavelengths_nm[b]},
                     {"held_out", bool(r.held_out[b])},
                     {"psnr", r.psnr_db[b]}});
  return {{"truth", r.clean ? "clean" : "stored"},
          {"views", r.views},
          {"trained_psnr", r.trained_mean_db()},
          {"held_out_psnr", r.held_out_mean_db()},
          {"skipped_nm", r.skipped_nm},
          {"bands", bands}};
}

std::string format_held_out(const HeldOutBands& r) {
  int held = 0;
  for (bool h : r.held_out) held += h;
  char line[256];
  std::snprintf(line, sizeof line,
                "held-out bands (%s truth, %d views): %d trained bands %.2f dB, %d held-out "
                "bands %.2f dB (mean of per-band PSNR)\n",
                r.clean ? "clean" : "stored", r.views, int(r.held_out.size()) - held,
                r.trained_mean_db(), held, r.held_out_mean_db());
  std::string out = line;
  if (!r.skipped_nm.empty())
    out += "  " + std::to_string(r.skipped_nm.size()) +
           " held-out band(s) beyond the trained range are not measured (no extrapolation)\n";
  return out;
}

}  // namespace ddhgs::eval
