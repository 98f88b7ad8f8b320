// `ddhgs synth`: presets and the writer of a complete synthetic scene folder.
//
// Output (Hyper-NeRF compatible): transforms.json, hyperspectral/r_NNN.npy
// (noisy, uint16: value / 65535), clean/r_NNN.npy (clean ground truth, same
// type), images/r_NNN.png (pseudo-RGB of the clean reflectance x shading),
// points.ply (sparse points with rgb and spectra) and synth.json (parameters).
#pragma once
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace ddhgs::synth {

struct SynthConfig {
  std::string preset = "demo";
  uint64_t seed = 0;
  int width = 128, height = 96;  // pixels
  int bands = 40;
  double wl_min_nm = 400, wl_max_nm = 1000;  // first and last band centres
  int views = 40;
  int rings = 3;
  double min_elevation_deg = 12, max_elevation_deg = 55;
  double fov_deg = 40;  // horizontal
  double fill = 0.95;   // fraction of the frame (each axis) the plant's box fills
  // Radial lens distortion of every camera (OPENCV k1; negative: barrel),
  // for scenes that exercise undistortion at load.
  double k1 = 0;
  int supersample = 3;  // rays per pixel along each axis
  double noise_scale = 1.0;
  bool noisy_edges = false;  // noise grows as response^-2 instead of response^-1
  bool ground = true;
  int points = 3000;            // sparse points in points.ply (about)
  double point_jitter = 0.004;  // scene units, like an SfM cloud's error
  // The "rig" preset: raw TIFF captures of a five-camera multispectral rig
  // instead of registered cubes (synth/rig_scene.h); bands and the
  // wavelength range are the rig's.
  bool rig = false;
  // With rig: a strip of `views` nadir captures flown over the plant and its
  // ground at this forward overlap (0 < overlap < 1), instead of a ring.
  bool nadir = false;
  double overlap = 0.7;
  // With nadir: `views` captures flown as this many parallel lines
  // (views a multiple of lines), neighbouring lines overlapping by
  // side_overlap of a frame's width across them; at altitude_m above the
  // ground (0: three plant heights, as one strip is flown); and with
  // field_spacing_m > 0, a field of plants that far apart (metres) on ground
  // covering every capture instead of the one plant on its disc.
  int lines = 1;
  double side_overlap = 0.6;
  double altitude_m = 0;
  double field_spacing_m = 0;
  // With rig: each capture's true illumination is what its DLS reports (and
  // the panel capture saw) times a factor, as under a passing cloud the DLS
  // does not see: light_factors, one per capture, or when that is empty
  // factors drawn from the seed uniformly within 1 +- light_change (0: the
  // light never changes).
  double light_change = 0;
  std::vector<double> light_factors;
  // With rig: each band camera but camera 1 (the rig's frame) truly sits
  // turned by this angle (degrees, about a random axis) and with its centre
  // this far (cm, in a random direction across the rig's face) from where
  // its factory RigRelatives, which its metadata keeps, place it. Scene
  // units are metres.
  double rig_perturb_deg = 0;
  double rig_offset_cm = 0;
  // With rig: where the world's origin lies on the earth (WGS84 degrees;
  // the ground z = 0 at gps_ground_m above the ellipsoid): each capture's
  // EXIF GPS is its true position from there, world x east and y north in
  // metres of the origin's UTM zone (synth/geo_truth.h). By default a
  // field of Rothamsted Research, England.
  double gps_latitude_deg = 51.8091, gps_longitude_deg = -0.3727;
  double gps_ground_m = 120;
  // With rig: each capture's EXIF GPS is off its true position by a
  // seeded normal error of this standard deviation (metres) along each of
  // east, north and up, as a consumer receiver's is; the errors are
  // recorded in synth.json.
  double gps_noise_m = 0;
  // With nadir: the ground control points are printed on the ground as
  // survey targets, black and white 2 x 2 checkers 10 of the flight's
  // ground pixels a side, centred on each point (NE and SW quarters black).
  bool gcp_targets = false;
  // With nadir: cubes/ also holds held-out captures that the flight did not
  // take, midway between its neighbouring captures and lines
  // (synth/survey.h: between_captures), as NOVEL_NNNN in its test split
  // beside the flight's own held-out captures, so that a model is measured
  // over the whole survey and not only where the split's captures fall.
  bool novel_views = false;
  // A randomised variant of the preset's plant and light, drawn from the
  // seed (synth/variant.h: draw_variant); the framing's part, vary_framing,
  // is applied to the fields above before flags override them.
  bool vary = false;

  std::vector<double> wavelengths_nm() const;
};

// "demo", "bayspec", "surface-optics", "noisy-edges", "rig", "rig-nadir"; core::Error
// otherwise.
SynthConfig preset_config(const std::string& name);
std::vector<std::string> preset_names();

struct SynthResult {
  int views = 0;
  int points = 0;
  double seconds = 0;
};

// Renders and writes the scene to out, built under a temporary name and put
// in place at the end (io::write_folder_atomically), so an interrupted run
// leaves nothing half-written. An existing scene written by ddhgs is
// replaced only with force; anything else there is refused.
// Throws core::Error naming the flag of the first value out of range.
void validate(const SynthConfig& config);

SynthResult write_synthetic_scene(const SynthConfig& config, const std::filesystem::path& out,
                                  bool force);

}  // namespace ddhgs::synth
