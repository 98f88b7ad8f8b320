#include "synth/variant.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <random>

namespace ddhgs::synth {

namespace {

// Uniform draws from one stream of (seed, stream).
class Draws {
 public:
  Draws(uint64_t seed, uint32_t stream) {
    std::seed_seq seq{uint32_t(seed), uint32_t(seed >> 32), stream, 0x7a41a7u};
    rng_.seed(seq);
  }
  double uniform(double lo, double hi) {
    return std::uniform_real_distribution<double>(lo, hi)(rng_);
  }
  // An integer in [lo, hi], each equally likely.
  int integer(int lo, int hi) { return std::min(hi, lo + int(uniform(0, hi - lo + 1))); }

 private:
  std::mt19937_64 rng_;
};

// A [lo, hi] range of width 2 * half around a centre drawn in [centre_lo, centre_hi].
void centred(Draws& d, double centre_lo, double centre_hi, double half, double* lo, double* hi) {
  const double centre = d.uniform(centre_lo, centre_hi);
  *lo = centre - half;
  *hi = centre + half;
}

Tint draw_tint(Draws& d, double gain_lo, double gain_hi, double shift_nm) {
  Tint t;
  t.gain = d.uniform(gain_lo, gain_hi);
  t.shift_nm = shift_nm > 0 ? d.uniform(-shift_nm, shift_nm) : 0.0;
  return t;
}

nlohmann::json tint_json(const Tint& t) {
  return {{"gain", t.gain}, {"shift_nm", t.shift_nm}};
}

}  // namespace

SceneVariant draw_variant(uint64_t seed) {
  Draws d(seed, 1);
  SceneVariant v;
  PlantStyle& p = v.plant;
  p.min_leaves = d.integer(5, 14);
  p.max_leaves = p.min_leaves + d.integer(0, 8);
  p.size = d.uniform(0.7, 1.3);
  p.leaf_aspect = d.uniform(0.75, 1.3);
  p.height = d.uniform(0.75, 1.4);
  p.droop = d.uniform(0.4, 1.6);
  p.lean = d.uniform(0, 0.2);
  centred(d, 0.5, 1.5, 0.25, &p.chlorophyll_lo, &p.chlorophyll_hi);
  centred(d, 0.6, 1.4, 0.2, &p.water_lo, &p.water_hi);
  centred(d, 0.32, 0.62, 0.07, &p.nir_plateau_lo, &p.nir_plateau_hi);
  p.yellowed_leaves = d.integer(0, 5);
  p.yellowed_senescence = d.uniform(0.2, 0.8);
  p.pot = draw_tint(d, 0.55, 1.4, 60);
  p.soil = draw_tint(d, 0.6, 1.5, 50);
  p.ground = draw_tint(d, 0.4, 1.8, 150);
  p.backdrop = draw_tint(d, 0.3, 2.0, 0);

  Lighting& l = v.lighting;
  const double azimuth = d.uniform(0, 2 * M_PI), elevation = d.uniform(25, 80) * M_PI / 180;
  l.to_light = {std::cos(elevation) * std::cos(azimuth), std::cos(elevation) * std::sin(azimuth),
                std::sin(elevation)};
  l.sun = d.uniform(0.4, 1.2);
  l.ambient = d.uniform(0.08, 0.45);
  // Both drawn always, so the later draws do not depend on this one.
  const bool no_backdrop = d.uniform(0, 1) < 0.25;
  const double backdrop = d.uniform(0.3, 1.0);
  l.backdrop = no_backdrop ? 0.0 : backdrop;
  l.lamp_temperature_k = d.uniform(2400, 6500);
  l.exposure = d.uniform(0.45, 1.0);
  return v;
}

void vary_framing(SynthConfig& c) {
  Draws d(c.seed, 2);
  c.fill = d.uniform(0.6, 0.98);
  c.fov_deg *= d.uniform(0.8, 1.25);
  c.rings = std::clamp(c.rings + d.integer(-1, 1), 1, 5);
  c.min_elevation_deg = std::clamp(c.min_elevation_deg + d.uniform(-5, 10), 0.0, 40.0);
  c.max_elevation_deg =
      std::clamp(c.max_elevation_deg + d.uniform(-15, 10), c.min_elevation_deg + 5, 75.0);
}

nlohmann::json describe_variant(const SceneVariant& v) {
  const PlantStyle& p = v.plant;
  const Lighting& l = v.lighting;
  return {{"leaves", {p.min_leaves, p.max_leaves}},
          {"leaf_size", p.size},
          {"leaf_aspect", p.leaf_aspect},
          {"height", p.height},
          {"droop", p.droop},
          {"lean", p.lean},
          {"chlorophyll", {p.chlorophyll_lo, p.chlorophyll_hi}},
          {"water", {p.water_lo, p.water_hi}},
          {"nir_plateau", {p.nir_plateau_lo, p.nir_plateau_hi}},
          {"yellowed_leaves", p.yellowed_leaves},
          {"yellowed_senescence", p.yellowed_senescence},
          {"tints",
           {{"pot", tint_json(p.pot)},
            {"soil", tint_json(p.soil)},
            {"ground", tint_json(p.ground)},
            {"backdrop", tint_json(p.backdrop)}}},
          {"lamp_temperature_k", l.lamp_temperature_k},
          {"exposure", l.exposure}};
}

}  // namespace ddhgs::synth
