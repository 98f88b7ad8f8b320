// Analytic spectra of the synthetic scenes: material reflectances, the lamp,
// the sensor's quantum efficiency and the per-band noise model. All are smooth
// closed-form functions of wavelength (nm) so any band grid can be sampled.
#pragma once

namespace ddhgs::synth {

// Per-leaf biochemistry, roughly around 1 for a healthy leaf.
struct LeafTraits {
  double chlorophyll = 1.0;  // deepens the 430/660 nm troughs, shifts the red edge right
  double water = 1.0;        // depth of the ~970 nm dip and the rise towards 1200 nm
  double nir_plateau = 0.5;  // reflectance of the near-infrared plateau
  double senescence = 0.0;   // 0 green .. 1 yellow-brown
};

// Reflectances in [0, 1].
double leaf_reflectance(double wavelength_nm, const LeafTraits& traits);
double terracotta_reflectance(double wavelength_nm, double darkness);  // darkness in [0, 1]
double soil_reflectance(double wavelength_nm, double moisture);        // moisture in [0, 1]
double mat_reflectance(double wavelength_nm, double tone);  // ground disc; tone in [0, 1]
double background_reflectance(double wavelength_nm);        // neutral grey backdrop

// Relative lamp power, max ~1: a halogen black body plus some daylight fill,
// so the blue end is dim but not empty.
double lamp_power(double wavelength_nm, double temperature_k = 3200.0);
// Sensor quantum efficiency: a bump peaking at 680 nm that falls to ~15 % at
// 400 and 1100 nm.
double sensor_response(double wavelength_nm);

struct NoiseModel {
  double shot = 1.5e-4;     // shot-noise variance per unit signal at full response
  double read = 1e-3;       // read-noise std at full response
  double scale = 1.0;       // multiplies the std (--noise-scale)
  double edge_power = 1.0;  // noise grows as response^-edge_power (2: noisy edges)
};
// Standard deviation of the measured value for a clean signal in [0, 1] and a
// sensor response in (0, 1]: sqrt(shot s / q + (read / q)^2) with q = response^edge_power.
double noise_std(double signal, double response, const NoiseModel& model);

}  // namespace ddhgs::synth
