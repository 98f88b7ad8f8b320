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

// A survey target printed on the ground (z = 0): a 2 x 2 checker of
// black and white squares around (x, y), half a side `half` (scene units);
// the north-east and south-west quarters black.
struct GroundTarget {
  double x = 0, y = 0, half = 0;
};

class PlantScene {
 public:
  // Same seed, same plant. ground: add the textured ground disc.
  static PlantScene build(uint64_t seed, bool ground);

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
