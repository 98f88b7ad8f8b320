#include "synth/survey.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "core/error.h"

namespace ddhgs::synth {
using core::Vec3;

namespace {

// A nadir capture at (x, y, height): image x along +x, image y along -y.
core::Camera nadir_camera(const core::Intrinsics& intr, double x, double y, double height) {
  core::Camera camera;
  camera.intrinsics = intr;
  camera.world_to_camera =
      core::look_at(Vec3{x, y, height}, Vec3{x, y, 0}, Vec3{0, 1, 0});  // looking down (-z)
  return camera;
}

// The survey's grid: its height, the steps along and across the lines and
// the grid's centre.
struct SurveyGrid {
  core::Intrinsics intr;
  double height = 0, step = 0, side_step = 0;
  int per_line = 0;
  Vec3 centre;
  // Position i (0 .. per_line - 1, fractions between) along line `line`.
  double x(double i) const { return centre.x + (i - 0.5 * (per_line - 1)) * step; }
  double y(double line, int lines) const {
    return centre.y + (line - 0.5 * (lines - 1)) * side_step;
  }
};

SurveyGrid survey_grid(const PlantScene& scene, const RigOptions& options, const Flight& flight) {
  core::require(flight.lines >= 1 && options.views % flight.lines == 0 && flight.overlap > 0 &&
                    flight.overlap < 1 && flight.side_overlap >= 0 && flight.side_overlap < 1,
                "synth: expected views a multiple of lines, 0 < overlap < 1 and "
                "0 <= side overlap < 1");
  SurveyGrid g;
  g.intr = rig_intrinsics(options);
  // Flown at least three plant heights up, as a field is flown (the plant's
  // top must stay in view of the neighbouring captures: from a third of the
  // plant's height above it, a strip at 70 % overlap saw each leaf-top once),
  // and high enough that a frame's width covers three quarters of the
  // ground disc's radius.
  g.height =
      flight.altitude_m > 0
          ? flight.altitude_m
          : std::max(0.75 * scene.ground_radius * g.intr.fx / options.width, 3 * scene.box_max.z);
  g.step = g.height * options.width / g.intr.fx * (1 - flight.overlap);
  g.side_step = g.height * options.height / g.intr.fy * (1 - flight.side_overlap);
  g.per_line = options.views / flight.lines;
  g.centre = scene.centre();
  return g;
}

}  // namespace

std::vector<core::Camera> nadir_survey(const PlantScene& scene, const RigOptions& options,
                                       const Flight& flight) {
  const SurveyGrid g = survey_grid(scene, options, flight);
  std::vector<core::Camera> cameras;
  for (int line = 0; line < flight.lines; ++line)
    for (int j = 0; j < g.per_line; ++j) {
      const int i = line % 2 == 0 ? j : g.per_line - 1 - j;
      cameras.push_back(nadir_camera(g.intr, g.x(i), g.y(line, flight.lines), g.height));
    }
  return cameras;
}

std::vector<core::Camera> between_captures(const PlantScene& scene, const RigOptions& options,
                                           const Flight& flight) {
  const SurveyGrid g = survey_grid(scene, options, flight);
  std::vector<core::Camera> cameras;
  const int gaps = std::max(flight.lines - 1, 1);
  for (int k = 0; k < gaps; ++k) {
    const double line = flight.lines > 1 ? k + 0.5 : 0;
    for (int i = 0; i + 1 < g.per_line; ++i)
      cameras.push_back(nadir_camera(g.intr, g.x(i + 0.5), g.y(line, flight.lines), g.height));
  }
  return cameras;
}

void plant_field(PlantScene& scene, const std::vector<core::Camera>& cameras, double spacing_m,
                 uint64_t seed) {
  core::require(spacing_m >= 1.5, "synth: expected --field-spacing >= 1.5 m");
  // The footprints' bounding box on the ground: the corner rays' hits.
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  for (const core::Camera& camera : cameras) {
    const core::Intrinsics& k = camera.intrinsics;
    for (const double px : {0.0, double(k.width)})
      for (const double py : {0.0, double(k.height)}) {
        const Ray ray = camera_ray(camera, px, py);
        core::require(ray.dir.z < -1e-6, "synth: a camera's frame does not look down at the field");
        const Vec3 hit = ray.origin + ray.dir * (-ray.origin.z / ray.dir.z);
        x0 = std::min(x0, hit.x);
        x1 = std::max(x1, hit.x);
        y0 = std::min(y0, hit.y);
        y1 = std::max(y1, hit.y);
      }
  }
  scene.ground_radius =
      std::hypot(std::max(std::abs(x0), std::abs(x1)), std::max(std::abs(y0), std::abs(y1))) +
      spacing_m;
  std::seed_seq seq{uint32_t(seed), uint32_t(seed >> 32), 0xf1e1du};
  std::mt19937_64 rng(seq);
  std::uniform_real_distribution<double> jitter(-0.25 * spacing_m, 0.25 * spacing_m);
  scene.plants.clear();
  // A grid through the origin, so that the field keeps the plant the
  // preset's single-plant scene has there.
  const int i0 = int(std::ceil(x0 / spacing_m)), i1 = int(std::floor(x1 / spacing_m));
  const int j0 = int(std::ceil(y0 / spacing_m)), j1 = int(std::floor(y1 / spacing_m));
  for (int j = j0; j <= j1; ++j)
    for (int i = i0; i <= i1; ++i) {
      const double dx = jitter(rng), dy = jitter(rng);
      scene.plants.push_back(i == 0 && j == 0 ? Vec3{0, 0, 0}
                                              : Vec3{i * spacing_m + dx, j * spacing_m + dy, 0});
    }
  if (scene.plants.empty()) scene.plants.push_back(Vec3{0, 0, 0});
}

}  // namespace ddhgs::synth
