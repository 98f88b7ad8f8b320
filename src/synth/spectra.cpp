#include "synth/spectra.h"

#include <algorithm>
#include <cmath>

#include "core/colour.h"

namespace ddhgs::synth {

namespace {

double sigmoid(double x) {
  return 1.0 / (1.0 + std::exp(-x));
}
double bump(double nm, double centre_nm, double width_nm) {
  double z = (nm - centre_nm) / width_nm;
  return std::exp(-0.5 * z * z);
}

}  // namespace

double leaf_reflectance(double nm, const LeafTraits& traits) {
  const double sen = std::clamp(traits.senescence, 0.0, 1.0);
  const double chl = std::max(0.05, traits.chlorophyll * (1.0 - 0.7 * sen));
  // Visible: chlorophyll absorbs blue (~435 nm) and red (~668 nm) and leaves
  // the green peak; yellowing leaves reflect from ~530 nm on (carotenoids stay).
  double visible =
      0.03 + 0.10 * bump(nm, 550, 32) / std::sqrt(chl) + 0.22 * sen * sigmoid((nm - 530) / 25);
  visible *= (1 - 0.5 * std::min(1.0, chl) * bump(nm, 668, 16)) *
             (1 - 0.3 * std::min(1.0, chl) * bump(nm, 435, 20));
  // Near infrared: mesophyll scattering gives a plateau that declines slowly;
  // liquid water absorbs around 970 nm and increasingly towards 1200 nm.
  double decline = 1 - 0.06 * std::clamp((nm - 800) / 300, 0.0, 1.0);
  double water_absorbance = traits.water * (0.10 * bump(nm, 975, 28) + 0.35 * bump(nm, 1200, 50));
  double nir = traits.nir_plateau * (1 - 0.15 * sen) * decline * std::exp(-water_absorbance);
  // Red edge: more chlorophyll moves it towards longer wavelengths.
  double edge_nm = 705 + 12 * chl;
  double s = sigmoid((nm - edge_nm) / 11);
  return (1 - s) * visible + s * nir;
}

double terracotta_reflectance(double nm, double darkness) {
  // Iron oxides: dark in the blue, rising through orange-red into the NIR.
  double r = 0.07 + 0.33 * sigmoid((nm - 575) / 35) + 0.06 * std::clamp((nm - 700) / 400, 0.0, 1.0);
  return r * (1 - 0.35 * std::clamp(darkness, 0.0, 1.0));
}

double soil_reflectance(double nm, double moisture) {
  double dry = 0.06 + 0.22 * (1 - std::exp(-(nm - 380) / 450));
  double m = std::clamp(moisture, 0.0, 1.0);
  return dry * (1 - 0.5 * m) * (1 - 0.08 * m * bump(nm, 975, 30));
}

double mat_reflectance(double nm, double tone) {
  return (0.30 + 0.12 * sigmoid((nm - 600) / 60)) * (1 - 0.25 * std::clamp(tone, 0.0, 1.0));
}

double background_reflectance(double nm) {
  return 0.33 + 0.02 * (nm - 700) / 300;
}

double lamp_power(double nm, double temperature_k) {
  double peak_nm = 2.897771955e6 / temperature_k;  // Wien's displacement law
  double halogen =
      core::planck_radiance(nm, temperature_k) / core::planck_radiance(peak_nm, temperature_k);
  return 0.65 * halogen + 0.35;
}

double sensor_response(double nm) {
  // Asymmetric bump: silicon loses blue photons at the surface and NIR photons
  // pass through; widths chosen so 400 and 1100 nm sit at ~15 %.
  double width_nm = nm < 680 ? 144 : 216;
  return 0.02 + 0.98 * bump(nm, 680, width_nm);
}

double noise_std(double signal, double response, const NoiseModel& model) {
  double q = std::pow(std::max(response, 1e-3), model.edge_power);
  double variance = model.shot * std::max(signal, 0.0) / q + (model.read / q) * (model.read / q);
  return model.scale * std::sqrt(variance);
}

}  // namespace ddhgs::synth
