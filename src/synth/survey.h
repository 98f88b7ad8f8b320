// Nadir surveys of the rig presets: flight lines of captures looking
// straight down, and the field of plants they fly over.
#pragma once
#include <cstdint>
#include <vector>

#include "core/camera.h"
#include "synth/plant.h"
#include "synth/render.h"

namespace ddhgs::synth {

struct Flight {
  int lines = 1;              // parallel flight lines along world x, spaced along y
  double overlap = 0.7;       // forward: of a frame's length along its line
  double side_overlap = 0.6;  // between neighbouring lines: of a frame's width across them
  double altitude_m = 0;      // above the ground (z = 0); 0: the automatic height
};

// options.views captures (options.views / flight.lines per line, a
// multiple) looking straight down, the lines centred on the scene's centre
// and flown back and forth (a serpentine, as a survey is flown), image x
// along +x and image y along -y on every line. The automatic height is three
// times the plant's height, or where a frame's width covers three quarters
// of the ground disc's radius, if higher.
std::vector<core::Camera> nadir_survey(const PlantScene& scene, const RigOptions& options,
                                       const Flight& flight);

// Novel viewpoints over the same survey, for measuring a model away from
// the flight's own captures: one nadir capture (same height, heading and
// lens) midway between each four neighbouring captures of the grid, or
// between each two on a single line: (views / lines - 1) x (lines - 1)
// captures, or views - 1 on one line, ordered line by line along +x.
std::vector<core::Camera> between_captures(const PlantScene& scene, const RigOptions& options,
                                           const Flight& flight);

// Grows the scene into a field under the cameras: the ground disc covers
// every camera's footprint on z = 0, and copies of the plant stand on a grid
// of spacing_m (metres, at least 1.5) over the footprints' bounding box,
// each moved by up to a quarter of the spacing (drawn from seed).
void plant_field(PlantScene& scene, const std::vector<core::Camera>& cameras, double spacing_m,
                 uint64_t seed);

}  // namespace ddhgs::synth
