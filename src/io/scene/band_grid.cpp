#include "io/scene/band_grid.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "core/error.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

// Assumed grid when neither the dataset nor the cubes name usable
// wavelengths: the two sensors of the Hyper-NeRF data by band count, else
// BaySpec's range.
std::vector<double> assumed_wavelengths(int64_t bands, std::string* range) {
  double lo = 400, hi = 1100;
  if (bands == 128) lo = 370;
  *range = std::to_string(int(lo)) + "-" + std::to_string(int(hi)) + " nm";
  std::vector<double> out;
  for (int64_t b = 0; b < bands; ++b)
    out.push_back(bands > 1 ? lo + (hi - lo) * double(b) / double(bands - 1) : lo);
  return out;
}

bool distinct_and_finite(const std::vector<double>& nm) {
  std::vector<double> sorted = nm;
  std::sort(sorted.begin(), sorted.end());
  return std::all_of(nm.begin(), nm.end(), [](double v) { return std::isfinite(v); }) &&
         std::adjacent_find(sorted.begin(), sorted.end()) == sorted.end();
}

// Band order that makes the wavelengths strictly increasing (identity when
// they already are, or for RGB), after replacing an unusable grid.
std::vector<int> band_order(Scene& scene, std::vector<double>& source_nm, bool rgb,
                            const fs::path& origin) {
  std::vector<int> order(source_nm.size());
  std::iota(order.begin(), order.end(), 0);
  if (rgb) return order;
  if (!distinct_and_finite(source_nm)) {
    std::string range;
    source_nm = assumed_wavelengths(int64_t(source_nm.size()), &range);
    scene.warnings.push_back(origin.string() +
                             ": the wavelengths repeat or are not finite numbers; using the "
                             "band index instead (bands in file order, taken as evenly spaced "
                             "over " +
                             range + ")");
    return order;
  }
  if (std::is_sorted(source_nm.begin(), source_nm.end())) return order;
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return source_nm[size_t(a)] < source_nm[size_t(b)]; });
  scene.warnings.push_back(origin.string() +
                           ": the wavelengths are not in increasing order; the bands are "
                           "reordered by wavelength");
  return order;
}

}  // namespace

std::vector<double> source_wavelengths(Scene& scene, bool rgb,
                                       const std::vector<double>& dataset_nm,
                                       const std::vector<double>& cube_nm, int64_t bands,
                                       const fs::path& origin, const fs::path& first_file) {
  if (rgb) {
    core::require(bands == 3, first_file,
                  "expected an RGB image (3 channels), found " + std::to_string(bands));
    return rgb_wavelengths_nm();
  }
  if (!dataset_nm.empty()) {
    if (int64_t(dataset_nm.size()) != bands)
      throw core::Error(origin, "lists " + std::to_string(dataset_nm.size()) +
                                    " wavelengths, but " + first_file.string() + " has " +
                                    std::to_string(bands) + " bands");
    return dataset_nm;
  }
  if (int64_t(cube_nm.size()) == bands) return cube_nm;
  std::string range;
  std::vector<double> assumed = assumed_wavelengths(bands, &range);
  scene.warnings.push_back("no wavelengths in the dataset or its cubes; assuming " +
                           std::to_string(bands) + " bands evenly spaced over " + range);
  return assumed;
}

void select_bands(Scene& scene, std::vector<double> source_nm, bool rgb, const fs::path& origin) {
  const LoadOptions& o = scene.options;
  core::require(o.bin >= 1, "--bin must be at least 1");
  std::vector<int> kept;
  for (int b : band_order(scene, source_nm, rgb, origin))
    if (source_nm[size_t(b)] >= o.band_min_nm && source_nm[size_t(b)] <= o.band_max_nm)
      kept.push_back(b);
  if (kept.empty())
    throw core::Error(origin, "no band lies in the requested range " +
                                  std::to_string(o.band_min_nm) + "-" +
                                  std::to_string(o.band_max_nm) + " nm");
  size_t groups = kept.size() / size_t(o.bin);
  if (groups == 0)
    throw core::Error(origin, "only " + std::to_string(kept.size()) +
                                  " bands selected, fewer than --bin " + std::to_string(o.bin));
  if (kept.size() % size_t(o.bin) != 0)
    scene.warnings.push_back("binning by " + std::to_string(o.bin) + " drops the last " +
                             std::to_string(kept.size() % size_t(o.bin)) + " band(s)");
  kept.resize(groups * size_t(o.bin));
  core::require(o.band_step >= 1, "data.band_step must be at least 1");
  // Every band_step-th group, from the first (the others are held out).
  std::vector<int> stepped;
  for (size_t g = 0; g < groups; g += size_t(o.band_step))
    stepped.insert(stepped.end(), kept.begin() + long(g * size_t(o.bin)),
                   kept.begin() + long((g + 1) * size_t(o.bin)));
  if (o.band_step > 1 && stepped.size() / size_t(o.bin) < 2)
    throw core::Error(origin, "data.band_step " + std::to_string(o.band_step) + " keeps " +
                                  std::to_string(stepped.size() / size_t(o.bin)) + " of " +
                                  std::to_string(groups) + " bands; it must keep at least 2");
  kept = stepped;
  groups = kept.size() / size_t(o.bin);
  scene.band_index = kept;
  scene.wavelengths_nm.clear();
  for (size_t g = 0; g < groups; ++g) {
    double sum = 0;
    for (int k = 0; k < o.bin; ++k) sum += source_nm[size_t(kept[g * size_t(o.bin) + size_t(k)])];
    scene.wavelengths_nm.push_back(sum / o.bin);
  }
}

}  // namespace ddhgs::io
