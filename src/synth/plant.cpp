#include "synth/plant.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

namespace ddhgs::synth {

using core::Vec3;

namespace {

constexpr double kEps = 1e-7;
enum Kind { kLeafKind, kCapsuleKind, kPotKind, kSoilKind, kGroundKind };

uint64_t splitmix(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

double smoothstep(double lo, double hi, double x) {
  double t = std::clamp((x - lo) / (hi - lo), 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

// Smallest root of a t^2 + b t + c = 0 above kEps for which accept(t) holds.
template <typename Accept>
double first_root(double a, double b, double c, Accept accept) {
  double roots[2];
  int count = 0;
  if (std::abs(a) < 1e-12) {
    if (std::abs(b) < 1e-12) return -1;
    roots[count++] = -c / b;
  } else {
    double disc = b * b - 4 * a * c;
    if (disc < 0) return -1;
    double s = std::sqrt(disc);
    double q = -0.5 * (b + (b >= 0 ? s : -s));  // avoids cancellation
    double r0 = q / a, r1 = q != 0 ? c / q : r0;
    roots[count++] = std::min(r0, r1);
    roots[count++] = std::max(r0, r1);
  }
  for (int i = 0; i < count; ++i)
    if (roots[i] > kEps && accept(roots[i])) return roots[i];
  return -1;
}

bool hits_sphere(const Ray& ray, const Vec3& centre, double radius) {
  Vec3 oc = ray.origin - centre;
  double b = oc.dot(ray.dir);
  double c = oc.dot(oc) - radius * radius;
  return c <= 0 || (b < 0 && b * b >= c);
}

// Leaf outline half-width at position a along the midrib (0 base .. length tip):
// an ellipse, widest a little below the middle, pointed at the tip.
double leaf_half_width(const Leaf& leaf, double a) {
  double s = 2 * a / leaf.length - 1;
  if (s <= -1 || s >= 1) return 0;
  return 0.5 * leaf.width * std::sqrt(1 - s * s) * (1 - 0.25 * s);
}

struct LeafLocal {
  double a, b;
};

LeafLocal leaf_coords(const Leaf& leaf, const Vec3& p) {
  Vec3 d = p - leaf.base;
  return {d.dot(leaf.u), d.dot(leaf.v)};
}

// Height of the blade above its frame plane: drooping tip, cupped sides.
double leaf_p2(const Leaf& leaf) {
  return -leaf.droop / leaf.length;
}
double leaf_q2(const Leaf& leaf) {
  return leaf.cup / leaf.width;
}

double intersect_leaf(const Leaf& leaf, const Ray& ray) {
  if (!hits_sphere(ray, leaf.bound_centre, leaf.bound_radius)) return -1;
  Vec3 o = ray.origin - leaf.base;
  double ox = o.dot(leaf.u), oy = o.dot(leaf.v), oz = o.dot(leaf.n);
  double dx = ray.dir.dot(leaf.u), dy = ray.dir.dot(leaf.v), dz = ray.dir.dot(leaf.n);
  double p2 = leaf_p2(leaf), q2 = leaf_q2(leaf);
  // oz + t dz = p2 (ox + t dx)^2 + q2 (oy + t dy)^2
  double a = p2 * dx * dx + q2 * dy * dy;
  double b = 2 * p2 * ox * dx + 2 * q2 * oy * dy - dz;
  double c = p2 * ox * ox + q2 * oy * oy - oz;
  return first_root(a, b, c, [&](double t) {
    double x = ox + t * dx, y = oy + t * dy;
    return std::abs(y) <= leaf_half_width(leaf, x);
  });
}

double intersect_sphere(const Vec3& centre, double radius, const Ray& ray) {
  Vec3 oc = ray.origin - centre;
  double b = ray.dir.dot(oc);
  double h = b * b - (oc.dot(oc) - radius * radius);
  if (h <= 0) return -1;
  double t = -b - std::sqrt(h);
  return t > kEps ? t : -1;
}

double intersect_capsule(const Capsule& cap, const Ray& ray) {
  Vec3 ba = cap.b - cap.a, oa = ray.origin - cap.a;
  double baba = ba.dot(ba), bard = ba.dot(ray.dir), baoa = ba.dot(oa);
  double a = baba - bard * bard;
  if (a < 1e-12 * baba) {  // ray along the axis: only the end caps can be hit first
    double ta = intersect_sphere(cap.a, cap.radius, ray);
    double tb = intersect_sphere(cap.b, cap.radius, ray);
    if (ta < 0 || (tb > 0 && tb < ta)) return tb;
    return ta;
  }
  // Infinite cylinder around the axis, scaled by baba to avoid divisions.
  double b = baba * ray.dir.dot(oa) - baoa * bard;
  double c = baba * oa.dot(oa) - baoa * baoa - cap.radius * cap.radius * baba;
  double h = b * b - a * c;
  if (h < 0) return -1;
  double t = (-b - std::sqrt(h)) / a;
  double y = baoa + t * bard;  // position along the axis, times |ba|
  if (y > 0 && y < baba) return t > kEps ? t : -1;
  return intersect_sphere(y <= 0 ? cap.a : cap.b, cap.radius, ray);
}

double intersect_pot(const Pot& pot, const Ray& ray) {
  const Vec3& o = ray.origin;
  const Vec3& d = ray.dir;
  double k = (pot.top_radius - pot.bottom_radius) / pot.height;
  double r0 = pot.bottom_radius + k * o.z;
  double a = d.x * d.x + d.y * d.y - k * k * d.z * d.z;
  double b = 2 * (o.x * d.x + o.y * d.y - k * d.z * r0);
  double c = o.x * o.x + o.y * o.y - r0 * r0;
  return first_root(a, b, c, [&](double t) {
    double z = o.z + t * d.z;
    return z >= 0 && z <= pot.height;
  });
}

// Horizontal disc at height z, radius r, seen from either side.
double intersect_disc(double z, double r, const Ray& ray) {
  if (std::abs(ray.dir.z) < 1e-12) return -1;
  double t = (z - ray.origin.z) / ray.dir.z;
  if (t <= kEps) return -1;
  double x = ray.origin.x + t * ray.dir.x, y = ray.origin.y + t * ray.dir.y;
  return x * x + y * y <= r * r ? t : -1;
}

}  // namespace

double value_noise(const Vec3& p, uint64_t seed) {
  double fx = std::floor(p.x), fy = std::floor(p.y), fz = std::floor(p.z);
  int64_t ix = int64_t(fx), iy = int64_t(fy), iz = int64_t(fz);
  auto fade = [](double t) { return t * t * t * (t * (t * 6 - 15) + 10); };
  double tx = fade(p.x - fx), ty = fade(p.y - fy), tz = fade(p.z - fz);
  auto lattice = [&](int64_t x, int64_t y, int64_t z) {
    uint64_t h =
        splitmix(seed ^ splitmix(uint64_t(x) ^ splitmix(uint64_t(y) ^ splitmix(uint64_t(z)))));
    return double(h >> 11) * (1.0 / 9007199254740992.0);
  };
  double v[2][2];
  for (int j = 0; j < 2; ++j)
    for (int k = 0; k < 2; ++k) {
      double a = lattice(ix, iy + j, iz + k), b = lattice(ix + 1, iy + j, iz + k);
      v[j][k] = a + (b - a) * tx;
    }
  double y0 = v[0][0] + (v[1][0] - v[0][0]) * ty;
  double y1 = v[0][1] + (v[1][1] - v[0][1]) * ty;
  return y0 + (y1 - y0) * tz;
}

PlantScene PlantScene::build(uint64_t seed, bool ground, const PlantStyle& style) {
  PlantScene scene;
  scene.seed = seed;
  scene.ground = ground;
  scene.style = style;
  std::mt19937_64 rng(splitmix(seed));
  auto uniform = [&](double lo, double hi) {
    return std::uniform_real_distribution<double>(lo, hi)(rng);
  };
  const Pot& pot = scene.pot;

  // Main stem: a gently leaning curve from the soil to the crown.
  const double stem_base_z = pot.soil_height - 0.02, crown_z = uniform(1.05, 1.2) * style.height;
  const double lean_x = uniform(-style.lean, style.lean), lean_y = uniform(-style.lean, style.lean);
  auto stem_point = [&](double t) {
    return Vec3{lean_x * t * t, lean_y * t * t, stem_base_z + t * (crown_z - stem_base_z)};
  };
  const int segments = 5;
  for (int s = 0; s < segments; ++s) {
    double t0 = double(s) / segments, t1 = double(s + 1) / segments;
    scene.stems.push_back({stem_point(t0), stem_point(t1), 0.016 - 0.007 * t0});
  }

  const int count = style.min_leaves + int(uniform(0, style.max_leaves - style.min_leaves + 1));
  const double azimuth0 = uniform(0, 2 * M_PI);
  for (int i = 0; i < count; ++i) {
    double f = double(i) / (count - 1);  // 0 lowest .. 1 top
    Vec3 on_stem = stem_point(0.2 + 0.8 * f);
    double azimuth = azimuth0 + i * 2.39996 + uniform(-0.25, 0.25);  // golden angle
    Vec3 out{std::cos(azimuth), std::sin(azimuth), 0.0};
    double petiole = uniform(0.06, 0.14) * (1 - 0.4 * f);
    Vec3 base = on_stem + (out + Vec3{0, 0, 0.6}).normalized() * petiole;
    scene.stems.push_back({on_stem, base, 0.006});

    Leaf leaf;
    leaf.index = i;
    leaf.base = base;
    leaf.length = (0.5 - 0.22 * f) * uniform(0.85, 1.15) * style.size;
    leaf.width = leaf.length * uniform(0.45, 0.62) * style.leaf_aspect;
    leaf.droop = uniform(0.25, 0.5) * style.droop;
    leaf.cup = uniform(0.1, 0.35);
    double elevation = (2 + 38 * f + uniform(-8, 8)) * M_PI / 180;
    leaf.u = out * std::cos(elevation) + Vec3{0, 0, std::sin(elevation)};
    Vec3 up{0, 0, 1};
    Vec3 n0 = (up - leaf.u * up.dot(leaf.u)).normalized();
    Vec3 v0 = n0.cross(leaf.u);
    double roll = uniform(-0.3, 0.3);
    leaf.v = v0 * std::cos(roll) + n0 * std::sin(roll);
    leaf.n = n0 * std::cos(roll) - v0 * std::sin(roll);
    leaf.bound_centre = leaf.base + leaf.u * (0.5 * leaf.length);
    leaf.bound_radius = std::hypot(0.5 * leaf.length, 0.5 * leaf.width) + leaf.droop * leaf.length +
                        leaf.cup * leaf.width / 4;
    scene.leaves.push_back(leaf);

    LeafTraits traits;
    traits.chlorophyll = uniform(style.chlorophyll_lo, style.chlorophyll_hi);
    traits.water = uniform(style.water_lo, style.water_hi);
    traits.nir_plateau = uniform(style.nir_plateau_lo, style.nir_plateau_hi);
    traits.senescence =
        i < style.yellowed_leaves ? uniform(0.15, style.yellowed_senescence) : uniform(0.0, 0.08);
    scene.traits.push_back(traits);
  }

  // Loose bounds (culling) from the leaves' spheres; a tight box from points
  // sampled on the blades, for framing the cameras.
  Vec3 lo{-pot.top_radius, -pot.top_radius, 0}, hi{pot.top_radius, pot.top_radius, pot.height};
  Vec3 tight_lo = lo, tight_hi = hi;
  auto grow = [](Vec3& lo, Vec3& hi, const Vec3& c, double r) {
    lo = {std::min(lo.x, c.x - r), std::min(lo.y, c.y - r), std::min(lo.z, c.z - r)};
    hi = {std::max(hi.x, c.x + r), std::max(hi.y, c.y + r), std::max(hi.z, c.z + r)};
  };
  for (const auto& leaf : scene.leaves) {
    grow(lo, hi, leaf.bound_centre, leaf.bound_radius);
    for (int i = 0; i <= 8; ++i)
      for (int j = -2; j <= 2; ++j) {
        double a = leaf.length * i / 8, b = leaf_half_width(leaf, a) * j / 2;
        double c = leaf_p2(leaf) * a * a + leaf_q2(leaf) * b * b;
        grow(tight_lo, tight_hi, leaf.base + leaf.u * a + leaf.v * b + leaf.n * c, 0);
      }
  }
  for (const auto& cap : scene.stems)
    for (const Vec3& end : {cap.a, cap.b}) {
      grow(lo, hi, end, cap.radius);
      grow(tight_lo, tight_hi, end, cap.radius);
    }
  scene.bound_centre_ = (lo + hi) * 0.5;
  scene.bound_radius_ = (hi - lo).norm() * 0.5;
  scene.box_min = tight_lo;
  scene.box_max = tight_hi;
  return scene;
}

bool PlantScene::nearest(const Ray& ray, double max_t, bool any, Nearest* out) const {
  double best = max_t;
  bool found = false;
  size_t copy = 0;
  auto consider = [&](double t, int k, int i) {
    if (t > 0 && t < best) {
      best = t;
      *out = {t, k, i, copy};
      found = true;
    }
  };
  for (copy = 0; copy < plants.size() && !(any && found); ++copy) {
    // The copy's parts in its own frame: the ray moved by minus its offset.
    const Ray local{ray.origin - plants[copy], ray.dir};
    if (!hits_sphere(local, bound_centre_, bound_radius_)) continue;
    for (size_t i = 0; i < leaves.size() && !(any && found); ++i)
      consider(intersect_leaf(leaves[i], local), kLeafKind, int(i));
    for (size_t i = 0; i < stems.size() && !(any && found); ++i)
      consider(intersect_capsule(stems[i], local), kCapsuleKind, int(i));
    consider(intersect_pot(pot, local), kPotKind, 0);
    double k = (pot.top_radius - pot.bottom_radius) / pot.height;
    consider(intersect_disc(pot.soil_height, pot.bottom_radius + k * pot.soil_height, local),
             kSoilKind, 0);
  }
  copy = 0;
  if (ground) consider(intersect_disc(0.0, ground_radius, ray), kGroundKind, 0);
  return found;
}

bool PlantScene::intersect(const Ray& ray, SurfaceHit* hit) const {
  Nearest found;
  if (!nearest(ray, std::numeric_limits<double>::infinity(), false, &found)) return false;
  shade(ray, found, hit);
  return true;
}

bool PlantScene::occluded(const Ray& ray, double max_t) const {
  Nearest found;
  return nearest(ray, max_t, true, &found);
}

void PlantScene::shade(const Ray& ray, const Nearest& found, SurfaceHit* hit) const {
  const double t = found.t;
  const int kind = found.kind, index = found.index;
  hit->t = t;
  hit->point = ray.origin + ray.dir * t;
  // A plant's parts are shaded in its copy's frame, the ground in the world's.
  const Vec3 p = kind == kGroundKind ? hit->point : hit->point - plants[found.copy];
  Vec3 normal{0, 0, 1};
  switch (kind) {
    case kLeafKind: {
      const Leaf& leaf = leaves[index];
      LeafLocal l = leaf_coords(leaf, p);
      Vec3 local{-2 * leaf_p2(leaf) * l.a, -2 * leaf_q2(leaf) * l.b, 1.0};
      normal = leaf.u * local.x + leaf.v * local.y + leaf.n * local.z;
      double s = l.a / leaf.length, across = std::abs(l.b) / (0.5 * leaf.width);
      // Paler midrib and lateral veins, yellowing tips and edges, mottling.
      double midrib = 0.55 * std::exp(-std::pow(l.b / (0.035 * leaf.width), 2));
      double veins = 0.3 * std::pow(0.5 + 0.5 * std::cos(2 * M_PI * (7 * s - 2.5 * across)), 24) *
                     smoothstep(0.05, 0.2, across);
      double tips = 0.35 * smoothstep(0.75, 1.0, s) + 0.2 * smoothstep(0.8, 1.0, across);
      double mottle = 0.25 * value_noise(p * 9.0, seed ^ uint64_t(index + 1));
      hit->mix = float(std::clamp(midrib + veins + tips + mottle - 0.1, 0.0, 1.0));
      hit->material_a = kLeafMaterials + 2 * leaf.index;
      hit->material_b = hit->material_a + 1;
      hit->specular = 0.08f;
      hit->shininess = 35;
      break;
    }
    case kCapsuleKind: {
      const Capsule& cap = stems[index];
      Vec3 ba = cap.b - cap.a;
      double h = std::clamp((p - cap.a).dot(ba) / ba.dot(ba), 0.0, 1.0);
      normal = p - (cap.a + ba * h);
      hit->material_a = hit->material_b = kStem;
      hit->mix = 0;
      hit->specular = 0.03f;
      hit->shininess = 15;
      break;
    }
    case kPotKind: {
      double k = (pot.top_radius - pot.bottom_radius) / pot.height;
      double r = pot.bottom_radius + k * p.z;
      normal = {p.x, p.y, -r * k};
      bool inside = normal.dot(ray.dir) > 0;
      // Mottled clay, a darker rim band and two thin grooves; inner wall darker.
      double mottle = 0.6 * value_noise(p * 14.0, seed ^ 0x9077ull);
      double rim = 0.45 * smoothstep(pot.height - 0.05, pot.height - 0.045, p.z);
      double grooves = 0.5 * (std::exp(-std::pow((p.z - 0.09) / 0.006, 2)) +
                              std::exp(-std::pow((p.z - 0.15) / 0.006, 2)));
      hit->mix = float(std::clamp(mottle + rim + grooves + (inside ? 0.4 : 0.0), 0.0, 1.0));
      hit->material_a = kPotLight;
      hit->material_b = kPotDark;
      hit->specular = 0.05f;
      hit->shininess = 10;
      break;
    }
    case kSoilKind:
      // Two octaves hide the lattice of a single value-noise octave.
      hit->mix = float(smoothstep(0.3, 0.7,
                                  0.6 * value_noise(p * 30.0, seed ^ 0x5011ull) +
                                      0.4 * value_noise(p * 71.0, seed ^ 0x5012ull)));
      hit->material_a = kSoilDry;
      hit->material_b = kSoilWet;
      hit->specular = 0;
      break;
    default: {  // ground disc: woven mat with slow blotches, or a target's paint
      for (const GroundTarget& target : targets) {
        const double dx = p.x - target.x, dy = p.y - target.y;
        if (std::abs(dx) < target.half && std::abs(dy) < target.half) {
          hit->mix = 0;
          hit->material_a = scene_materials() + ((dx > 0) == (dy > 0) ? 1 : 0);
          hit->material_b = hit->material_a;
          hit->specular = 0;
          normal = normal.normalized();
          hit->normal = normal.dot(ray.dir) > 0 ? normal * -1.0 : normal;
          return;
        }
      }
      double weave = 0.5 + 0.5 * std::sin(60 * p.x) * std::sin(60 * p.y);
      double blotch = value_noise(p * 4.0, seed ^ 0x6a7dull);
      hit->mix = float(std::clamp(0.35 * weave + 0.65 * blotch, 0.0, 1.0));
      hit->material_a = kMatLight;
      hit->material_b = kMatDark;
      hit->specular = 0.01f;
      hit->shininess = 5;
    }
  }
  normal = normal.normalized();
  hit->normal = normal.dot(ray.dir) > 0 ? normal * -1.0 : normal;
}

std::vector<std::function<double(double)>> PlantScene::material_spectra() const {
  std::vector<std::function<double(double)>> out(kLeafMaterials);
  // Gain 1 and shift 0 leave every value as the function gives it.
  auto tinted = [](const Tint& tint, double (*f)(double, double), double parameter) {
    return [tint, f, parameter](double nm) {
      return std::min(1.0, tint.gain * f(nm - tint.shift_nm, parameter));
    };
  };
  const Tint backdrop = style.backdrop;
  out[kBackground] = [backdrop](double nm) {
    return std::min(1.0, backdrop.gain * background_reflectance(nm - backdrop.shift_nm));
  };
  out[kMatLight] = tinted(style.ground, mat_reflectance, 0.0);
  out[kMatDark] = tinted(style.ground, mat_reflectance, 1.0);
  out[kPotLight] = tinted(style.pot, terracotta_reflectance, 0.0);
  out[kPotDark] = tinted(style.pot, terracotta_reflectance, 1.0);
  out[kSoilDry] = tinted(style.soil, soil_reflectance, 0.0);
  out[kSoilWet] = tinted(style.soil, soil_reflectance, 1.0);
  out[kStem] = [](double nm) { return leaf_reflectance(nm, LeafTraits{0.45, 1.0, 0.38, 0.15}); };
  for (const auto& t : traits) {
    out.push_back([t](double nm) { return leaf_reflectance(nm, t); });
    LeafTraits pale = t;
    pale.chlorophyll *= 0.55;
    pale.senescence = std::min(1.0, t.senescence + 0.45);
    out.push_back([pale](double nm) { return leaf_reflectance(nm, pale); });
  }
  if (!targets.empty()) {  // matte paint, flat across the spectrum
    out.push_back([](double) { return 0.6; });
    out.push_back([](double) { return 0.04; });
  }
  return out;
}

}  // namespace ddhgs::synth
