#include "eval/report_splats.h"

#include <torch/linalg.h>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <string>

#include "core/error.h"
#include "core/tensor_values.h"
#include "eval/report_views.h"
#include "eval/rgb_export.h"
#include "eval/vegetation_index.h"

namespace ddhgs::eval {
namespace {
using json = nlohmann::json;

// Raw bytes of a contiguous tensor, base64-encoded (little-endian host).
std::string tensor_base64(const torch::Tensor& t) {
  torch::Tensor c = t.contiguous();
  return base64(std::string(static_cast<const char*>(c.data_ptr()), size_t(c.nbytes())));
}

// Values in [low, high] as uint16 steps, for log scales (steps of ~1e-4 in
// log, far below what a viewer shows).
torch::Tensor quantise_u16(const torch::Tensor& values, double low, double high) {
  const double span = std::max(high - low, 1e-12);
  return ((values.to(torch::kFloat64) - low) / span * 65535.0)
      .round()
      .clamp(0, 65535)
      .to(torch::kInt32)
      .to(torch::kInt16);  // bit pattern of the uint16 value (LibTorch has no kUInt16 here)
}

json camera_json(const core::Camera& camera) {
  const core::Mat4& w2c = camera.world_to_camera;
  const core::Vec3 c = camera.center();
  const core::Intrinsics& k = camera.intrinsics;
  std::vector<double> rotation;  // world-to-camera rows: the camera's x, y, z axes in world
  for (int r = 0; r < 3; ++r)
    for (int col = 0; col < 3; ++col) rotation.push_back(w2c(r, col));
  return {{"center", {c.x, c.y, c.z}},
          {"rotation", rotation},
          {"fx", k.fx},
          {"fy", k.fy},
          {"cx", k.cx},
          {"cy", k.cy},
          {"width", k.width},
          {"height", k.height}};
}

// Linear sRGB (or display RGB) weights per band, [N][3], and whether the
// page applies the sRGB curve: pseudo-RGB as `render` shows it, or for
// bands outside the visible range three bands spread over the spectrum.
json rgb_weights(const std::vector<double>& wavelengths_nm, int64_t bands) {
  ColourMapping mapping;
  try {
    mapping = cie_mapping(wavelengths_nm, bands);
  } catch (const core::Error&) {
    std::vector<double> spread = {wavelengths_nm[size_t((bands - 1) * 3 / 4)],
                                  wavelengths_nm[size_t((bands - 1) / 2)],
                                  wavelengths_nm[size_t((bands - 1) / 4)]};
    mapping = band_mapping(wavelengths_nm, spread);
  }
  json weights = json::array();
  for (int64_t n = 0; n < bands; ++n)
    weights.push_back(core::to_doubles(mapping.linear.select(1, n)));
  return {{"weights", weights},
          {"srgb_curve", mapping.curve == ColourMapping::Curve::Srgb},
          {"title", mapping.description}};
}

// The vegetation indices the bands cover (eval/vegetation_index.h): their
// two broad bands as weights over the bands; the page computes (a - b) / (a + b).
json index_weights(const std::vector<double>& wavelengths_nm) {
  json out = json::array();
  for (const VegetationIndex& index : vegetation_indices()) {
    torch::Tensor map;
    try {
      map = index_band_map(index, wavelengths_nm);
    } catch (const core::Error&) {
      continue;  // a band outside the sensor's range
    }
    std::string upper = index.name;
    for (char& c : upper) c = char(std::toupper(static_cast<unsigned char>(c)));
    out.push_back({{"name", index.name},
                   {"title", upper + ": (" + index.a.name + " - " + index.b.name + ") / (" +
                                 index.a.name + " + " + index.b.name + "), -1 red to 1 green"},
                   {"a", core::to_doubles(map[0])},
                   {"b", core::to_doubles(map[1])}});
  }
  return out;
}

}  // namespace

torch::Tensor band_values(const model::Gaussians& gaussians) {
  return gaussians.colour.spectra(gaussians.sh_dc.detach() * model::kShC0).clamp(0, 1);
}

torch::Tensor SpectralBasis::reconstruct() const {
  torch::Tensor c = low + coefficients.to(torch::kFloat64) / 255.0 * (high - low);  // [G, K]
  return mean + c.matmul(vectors);
}

SpectralBasis spectral_basis(const torch::Tensor& values, double tolerance, int max_vectors) {
  const int64_t G = values.size(0), N = values.size(1);
  core::require(G > 0 && N > 0, "spectral basis: no values");
  SpectralBasis basis;
  torch::Tensor v = values.to(torch::kFloat64);
  basis.mean = v.mean(0);
  torch::Tensor centred = v - basis.mean;
  auto [eigenvalues, eigenvectors] =
      torch::linalg::eigh(centred.t().matmul(centred) / double(G), "L");
  // Ascending order: the leading components are the last columns.
  torch::Tensor discarded =
      eigenvalues.clamp_min(0).cumsum(0) / double(N);  // by how many are dropped
  int64_t K = 1;
  while (K < std::min<int64_t>(N, max_vectors) &&
         discarded[N - K - 1].item<double>() > tolerance * tolerance)
    ++K;
  basis.vectors = eigenvectors.narrow(1, N - K, K).flip({1}).t().contiguous();  // [K, N]
  torch::Tensor c = centred.matmul(basis.vectors.t());                          // [G, K]
  basis.low = std::get<0>(c.min(0));
  basis.high = std::get<0>(c.max(0));
  torch::Tensor span = (basis.high - basis.low).clamp_min(1e-12);
  basis.coefficients = ((c - basis.low) / span * 255.0).round().clamp(0, 255).to(torch::kUInt8);
  basis.rmse = (basis.reconstruct() - v).square().mean().sqrt().item<double>();
  return basis;
}

nlohmann::json splat_view_data(const model::Gaussians& gaussians, const io::Scene& scene,
                               const torch::Tensor& background, int start_view) {
  torch::NoGradGuard no_grad;
  const int64_t G = gaussians.size();
  core::require(G > 0, "report: the model has no Gaussians to show in 3D");
  // Half an 8-bit step: the basis is as faithful as the 8-bit coefficients.
  const SpectralBasis basis = spectral_basis(band_values(gaussians), 0.5 / 255);

  const torch::Tensor log_scales = gaussians.log_scales.detach();
  const double scale_low = log_scales.min().item<double>();
  const double scale_high = log_scales.max().item<double>();
  torch::Tensor quats = gaussians.quats.detach();
  quats = quats / quats.norm(2, 1, true).clamp_min(1e-12);
  torch::Tensor opacity = torch::sigmoid(gaussians.logit_opacities.detach().reshape({G}));

  json cameras = json::array();
  for (int v : scene.train) cameras.push_back(camera_json(scene.views[size_t(v)].camera));
  json vectors = json::array();
  for (int64_t k = 0; k < basis.vectors.size(0); ++k)
    vectors.push_back(core::to_doubles(basis.vectors[k]));

  return {
      {"count", G},
      {"means", tensor_base64(gaussians.means.detach().to(torch::kFloat32))},
      {"log_scales", tensor_base64(quantise_u16(log_scales, scale_low, scale_high))},
      {"log_scale_range", {scale_low, scale_high}},
      {"quats", tensor_base64((quats * 127.0).round().to(torch::kInt8))},
      {"opacity", tensor_base64((opacity * 255.0).round().to(torch::kUInt8))},
      {"basis",
       {{"mean", core::to_doubles(basis.mean)},
        {"vectors", vectors},
        {"low", core::to_doubles(basis.low)},
        {"high", core::to_doubles(basis.high)},
        {"rmse", basis.rmse},
        {"coefficients", tensor_base64(basis.coefficients)}}},
      {"pseudo_rgb", rgb_weights(scene.wavelengths_nm, scene.bands())},
      {"indices", index_weights(scene.wavelengths_nm)},
      {"background", core::to_doubles(background)},
      {"cameras", cameras},
      {"start", camera_json(scene.views[size_t(start_view)].camera)},
  };
}

}  // namespace ddhgs::eval
