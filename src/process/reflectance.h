// `ddhgs process --white W --dark D`: a hyperspectral camera's raw counts to
// reflectance through white and dark reference frames, per band and pixel:
//
//   reflectance = (raw - dark) / (white - dark) x white's reflectance
//
// A reference (a few lines of a push-broom camera, or whole frames of a
// snapshot camera) is averaged over all its rows into one value per column
// and band: a push-broom sensor's column is one detector element, which
// every line of the scan reuses. For a snapshot camera this keeps each
// column's response and averages away the rows' (its vignetting down the
// frame stays in the reflectance). Raw counts at the sensor's top count are
// saturated: their reflectance is a lower bound, and they are counted. A
// column and band whose white is at most its dark, or under 1 % of the
// band's median white - dark, is dead: its reflectance is set to 0, and
// counted too.
#pragma once
#include "core/tensor.h"

#include <nlohmann/json_fwd.hpp>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "io/cube/cube.h"
#include "process/cube_set.h"

namespace ddhgs::process {

// A column and band is dead when white - dark is at most this share of the
// band's median white - dark over the columns (or at most 0).
constexpr double kDeadReferenceShare = 0.01;

// The white reference's reflectance per band: "0.99" (every band), or a
// file of one value per band (one per line), or of wavelength_nm,reflectance
// lines (a header line and # comments allowed; interpolated linearly at the bands, which
// its wavelengths must cover). core::Error naming the file (or the option)
// on a value outside (0, 2], a count that is not the band count, or bands
// outside its wavelengths.
std::vector<double> parse_white_reflectance(const std::string& spec,
                                            const std::vector<double>& wavelengths_nm);

// A reference file as one value per column and band, float64 [W, B]: its
// counts averaged over all its rows. core::Error naming the file when its
// width or band count differs from the cubes'.
torch::Tensor read_reference(const std::filesystem::path& path, int64_t width, int64_t bands);

// The sensor's top count for raw samples of this type (255, 65535, ...);
// none for floating-point samples.
std::optional<double> top_count(io::SampleType type);

// What one cube's conversion found.
struct ReflectanceCounts {
  int64_t samples = 0;    // pixels x bands
  int64_t saturated = 0;  // raw samples at the top count
  int64_t dead = 0;       // dead columns x bands of the references
};

// The cube's reflectance, float32 [H, W, B]. white, dark: [W, B] from
// read_reference; white_reflectance: B values; saturation: the top count
// (none: no sample counts as saturated).
torch::Tensor to_reflectance(const io::Cube& raw, const torch::Tensor& white,
                             const torch::Tensor& dark,
                             const std::vector<double>& white_reflectance,
                             std::optional<double> saturation, ReflectanceCounts* counts);

// How `ddhgs process` calibrates raw cubes.
struct ReflectanceOptions {
  // References for every cube; empty: each cube's own (a Specim IQ layout's),
  // or no calibration when the layout has none.
  std::filesystem::path white, dark;
  std::string white_reflectance = "1";  // parse_white_reflectance's spec
  std::optional<double> saturation;     // top count; none: the raw sample type's
};

// Whether the cubes are raw counts to calibrate: references given, or
// found beside each cube.
bool calibrates(const CubeSet& cubes, const ReflectanceOptions& options);

// The references and settings of one process run, checked against the
// cubes (each reference's width and band count, the white reflectance)
// before anything is written; core::Error naming the file otherwise.
struct Calibration {
  std::vector<std::filesystem::path> white, dark;  // per cube
  std::vector<double> white_reflectance;           // per band
  std::optional<double> saturation;                // as given
  torch::Tensor given_white, given_dark;           // [W, B], read once when given
};
Calibration plan_calibration(const CubeSet& cubes, const ReflectanceOptions& options);

// Writes every cube's reflectance as dir/<name>.npy (float32 [H, W, B])
// and returns the cube set of those files. summary["reflectance"] gets the
// settings and the saturated and dead counts, per cube and in all; one log
// line gives the totals (a warning when any).
CubeSet write_reflectance_cubes(const CubeSet& cubes, const Calibration& calibration,
                                const std::filesystem::path& dir, nlohmann::json& summary);

}  // namespace ddhgs::process
