// The band grid of a scene: which wavelength each band of the files has, in
// which order the scene keeps them, and the selection and binning asked for.
#pragma once
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "io/scene/scene.h"

namespace ddhgs::io {

// Wavelengths (nm) of the bands in the files, by precedence: the RGB grid for
// an RGB scene, the dataset's list (core::Error naming origin when its length
// differs from `bands`), the cube's own, else an assumed grid (a warning in
// scene.warnings).
std::vector<double> source_wavelengths(Scene& scene, bool rgb,
                                       const std::vector<double>& dataset_nm,
                                       const std::vector<double>& cube_nm, int64_t bands,
                                       const std::filesystem::path& origin,
                                       const std::filesystem::path& first_file);

// Fills scene.band_index and scene.wavelengths_nm from the source grid and
// scene.options (--band-range, --bin). A hyperspectral grid always comes out
// strictly increasing, with a warning when it was not: distinct wavelengths
// in another order are sorted (the bands reordered with them); repeated or
// non-finite ones give way to an assumed grid in file order (a band-index
// axis). An RGB grid (610, 550, 465 nm) keeps its R, G, B order.
void select_bands(Scene& scene, std::vector<double> source_nm, bool rgb,
                  const std::filesystem::path& origin);

}  // namespace ddhgs::io
