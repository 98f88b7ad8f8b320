// `ddhgs synth --vary`: a randomised variant of a ring preset's scene, drawn
// from its seed, so that the scenes of a corpus (scripts/prior_corpus.sh)
// differ in shape, materials, light and framing rather than in noise alone.
//
// Every value is drawn uniformly within the range its field's comment gives
// (docs/commands.md lists them too). The plant and light come from one
// stream and the framing from another, so a flag that overrides a framing
// value (--fill, --fov-deg, ...) leaves the plant and light as they were.
#pragma once
#include <cstdint>
#include <nlohmann/json_fwd.hpp>

#include "synth/generate.h"
#include "synth/plant.h"
#include "synth/render.h"

namespace ddhgs::synth {

struct SceneVariant {
  // Leaves: min_leaves 5-14, max_leaves min + 0-8; size 0.7-1.3,
  // leaf_aspect 0.75-1.3, height 0.75-1.4, droop 0.4-1.6, lean 0-0.2.
  // Leaf biochemistry: ranges centred on a drawn value, chlorophyll
  // 0.5-1.5 +- 0.25, water 0.6-1.4 +- 0.2, NIR plateau 0.32-0.62 +- 0.07;
  // yellowed_leaves 0-5 with senescence up to 0.2-0.8.
  // Tints (gain, shift nm): pot 0.55-1.4, -60-60; soil 0.6-1.5, -50-50;
  // ground 0.4-1.8, -150-150; backdrop 0.3-2.0, 0.
  PlantStyle plant;
  // The light's direction: azimuth 0-360 degrees, elevation 25-80 degrees;
  // sun 0.4-1.2, ambient 0.08-0.45; backdrop none (0) one time in four,
  // else 0.3-1.0; lamp 2400-6500 K; exposure 0.45-1.0.
  Lighting lighting;
};

// The plant and light of seed's variant.
SceneVariant draw_variant(uint64_t seed);

// Redraws config's framing from config.seed, around its preset's values:
// fill 0.6-0.98, fov_deg x 0.8-1.25, rings -1 to +1 (within 1-5), the
// lowest elevation + (-5 to 10) degrees (within 0-40), the highest
// + (-15 to 10) degrees (within lowest + 5 to 75).
void vary_framing(SynthConfig& config);

// What synth.json records of a variant (`variant`).
nlohmann::json describe_variant(const SceneVariant& variant);

}  // namespace ddhgs::synth
