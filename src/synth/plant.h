// The procedural potted plant: geometry (leaves, stems, pot, soil, ground
// disc), an analytic ray intersector, and the surface materials.
//
// World frame: z up, scene units of about 1 = plant height; the pot stands on
// the ground plane z = 0 at the origin.
#pragma once
#include <cstdint>
#include <functional>
#include <vector>

#include "core/mat.h"
#include "synth/spectra.h"

namespace ddhgs::synth {

struct Ray {
  core::Vec3 origin;
  core::Vec3 dir;  // unit length
};

// A leaf blade: a quadric height field over an egg-shaped outline in its own
// frame (u along the midrib from the base, v across, n the upper side).
struct Leaf {
  core::Vec3 base, u, v, n;
  double length = 0, width = 0;  // scene units
  double droop = 0, cup = 0;     // curvature along the midrib and across the blade
  int index = 0;                 // material pair 2 * index, 2 * index + 1 after kLeafMaterials
  core::Vec3 bound_centre;
  double bound_radius = 0;
};

// Stems and petioles: segments with rounded ends.
struct Capsule {
  core::Vec3 a, b;
  double radius = 0;
};

struct Pot {
  double bottom_radius = 0.17, top_radius = 0.23, height = 0.30;  // truncated cone
  double soil_height = 0.27;
};

// Spectrum slots of a scene; leaves follow, two per leaf (green, yellowed).
enum MaterialSlot : int {
  kBackground = 0,
  kMatLight,
  kMatDark,
  kPotLight,
  kPotDark,
  kSoilDry,
  kSoilWet,
  kStem,
  kLeafMaterials,
};

// What a ray sees at its nearest hit, ready for shading.
struct SurfaceHit {
  double t = 0;
  core::Vec3 point, normal;  // normal faces the ray's origin
  int material_a = kBackground, material_b = kBackground;
  float mix = 0;        // 0: material_a, 1: material_b
  float specular = 0;   // Blinn-Phong strength
  float shininess = 1;  // Blinn-Phong exponent
};

// A material's reflectance as the plant's style tints it: gain x f(nm -
// shift_nm), at most 1. The default leaves f unchanged.
struct Tint {
  double gain = 1;
  double shift_nm = 0;
};

// What PlantScene::build draws its plant from. The defaults are the presets'
// plant; `ddhgs synth --vary` draws a style per seed (synth/variant.h).
struct PlantStyle {
  int min_leaves = 12, max_leaves = 16;  // leaf count, uniform in [min, max]; min >= 2
  double size = 1;                       // multiplies every leaf's length
  double leaf_aspect = 1;                // multiplies every leaf's width / length ratio
  double height = 1;                     // multiplies the crown's height above the ground
  double droop = 1;                      // multiplies every leaf's droop
  double lean = 0.08;                    // largest lean of the stem's top, scene units
  // Leaf biochemistry (LeafTraits), each drawn uniformly in [lo, hi].
  double chlorophyll_lo = 0.75, chlorophyll_hi = 1.3;
  double water_lo = 0.8, water_hi = 1.2;
  double nir_plateau_lo = 0.42, nir_plateau_hi = 0.56;
  // The lowest leaves are yellowing: senescence uniform in [0.15,
  // yellowed_senescence] (> 0.15); the others' in [0, 0.08].
  int yellowed_leaves = 2;
  double yellowed_senescence = 0.45;
  Tint pot, soil, ground, backdrop;
};

// A survey target printed on the ground (z = 0): a 2 x 2 checker of
// black and white squares around (x, y), half a side `half` (scene units);
// the north-east and south-west quarters black.
struct GroundTarget {
  double x = 0, y = 0, half = 0;
};

class PlantScene {
 public:
  // Same seed and style, same plant. ground: add the textured ground disc.
  static PlantScene build(uint64_t seed, bool ground, const PlantStyle& style = {});

  // Nearest hit along the ray with t > 0; false for the background.
  bool intersect(const Ray& ray, SurfaceHit* hit) const;
  // Whether anything blocks the ray before max_t (shadow rays).
  bool occluded(const Ray& ray, double max_t) const;

  // Reflectance of every material slot (kLeafMaterials + 2 * leaves
  // entries, then the targets' white and black when there are targets).
  std::vector<std::function<double(double)>> material_spectra() const;
  int material_count() const { return scene_materials() + (targets.empty() ? 0 : 2); }
  // The slots of the plant, pot and ground, without the targets' paint.
  int scene_materials() const { return kLeafMaterials + 2 * int(leaves.size()); }

  // Tight axis-aligned box of the plant and pot (not the ground), for framing.
  core::Vec3 box_min, box_max;
  core::Vec3 centre() const { return (box_min + box_max) * 0.5; }

  std::vector<Leaf> leaves;
  std::vector<LeafTraits> traits;  // one per leaf
  std::vector<Capsule> stems;
  Pot pot;
  // Where copies of the plant stand (world offsets of its pot, z = 0): one
  // at the origin, or a field of them under a survey (synth/survey.h).
  std::vector<core::Vec3> plants{core::Vec3{0, 0, 0}};
  bool ground = true;
  double ground_radius = 1.6;
  // Printed on the ground disc (none by default).
  std::vector<GroundTarget> targets;
  uint64_t seed = 0;
  PlantStyle style;

 private:
  // The nearest hit's distance, kind, part and plant copy (ground: copy 0).
  struct Nearest {
    double t = 0;
    int kind = 0, index = 0;
    size_t copy = 0;
  };
  bool nearest(const Ray& ray, double max_t, bool any, Nearest* out) const;
  void shade(const Ray& ray, const Nearest& found, SurfaceHit* hit) const;
  core::Vec3 bound_centre_;  // loose sphere around everything but the ground: ray culling
  double bound_radius_ = 1;
};

// Smooth value noise in [0, 1] (trilinear over hashed lattice values, quintic fade).
double value_noise(const core::Vec3& p, uint64_t seed);

}  // namespace ddhgs::synth
