// Spectral super-resolution: a model trained on every k-th band
// (data.band_step) rendered at the bands it never saw, by the colour model's
// interpolation map (core/band_map.h), and measured per band against the
// same scene loaded with every band: `ddhgs eval RUN --held-out-bands`.
#pragma once
#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "core/tensor.h"
#include "io/scene/scene.h"
#include "model/gaussians.h"

namespace ddhgs::eval {

struct HeldOutBands {
  std::vector<double> wavelengths_nm;  // the measured bands of the full scene
  std::vector<bool> held_out;          // per measured band: not trained on
  std::vector<double> psnr_db;         // per measured band, mean over the views
  std::vector<double> skipped_nm;      // held-out bands outside the trained range (not measured)
  bool clean = false;                  // against clean ground truth (else the stored views)
  int views = 0;
  double trained_mean_db() const;   // mean over the trained bands of psnr_db
  double held_out_mean_db() const;  // mean over the held-out bands
};

// all_bands: the run's scene loaded with every band (band_step 1);
// trained_nm: the model's wavelengths. background: [N trained].
HeldOutBands evaluate_held_out_bands(const io::Scene& all_bands, const model::Gaussians& gaussians,
                                     const std::vector<double>& trained_nm,
                                     const torch::Tensor& background,
                                     const std::vector<int>& views);

nlohmann::json to_json(const HeldOutBands& r);
std::string format_held_out(const HeldOutBands& r);

}  // namespace ddhgs::eval
