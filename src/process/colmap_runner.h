// `ddhgs process`, second step: COLMAP (feature extraction, matching,
// mapping; CPU SIFT) run as subprocesses.
#pragma once
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "io/colmap/colmap.h"

namespace ddhgs::process {

struct ColmapOptions {
  std::string binary;                  // empty: $DDHGS_COLMAP, else colmap on PATH
  std::string matcher = "exhaustive";  // or "sequential"
  // SIMPLE_PINHOLE (one focal length) by default: on a turntable capture a
  // PINHOLE fit let fy drift 46 % from fx (docs/benchmarks.md).
  std::string camera_model = "SIMPLE_PINHOLE";  // or PINHOLE
  std::vector<std::string> settings;            // "Section.key=value", routed by section
  int threads = 1;                              // COLMAP's num_threads for every stage
};

// Checks matcher and camera model (distorting models are refused: the
// renderer needs undistorted pinhole cameras) and the settings' syntax.
void check_colmap_options(const ColmapOptions& options);

// Absolute path of the COLMAP executable; core::Error saying how to install
// it when it cannot be found.
std::string find_colmap(const ColmapOptions& options);

// Runs feature_extractor, the matcher and mapper on work/database.db and
// images_dir, models to work/sparse/<k>, every line of output appended to
// log_path, one progress bar per stage. core::Error naming log_path when a
// stage fails.
void run_colmap(const ColmapOptions& options, const std::filesystem::path& images_dir,
                const std::filesystem::path& work, const std::filesystem::path& log_path);

// Index of the model with the most registered images (ties: most points);
// nullopt when models is empty.
std::optional<size_t> largest_model(const std::vector<io::ColmapModel>& models);

}  // namespace ddhgs::process
