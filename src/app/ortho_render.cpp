#include "app/ortho_render.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <iostream>

#include "core/colour.h"
#include "core/error.h"
#include "core/log.h"
#include "eval/figures.h"
#include "eval/orthomosaic.h"
#include "eval/vegetation_index.h"
#include "io/files/atomic_file.h"
#include "io/files/folder_lock.h"
#include "io/files/output_folder.h"
#include "io/geo/geotiff.h"
#include "io/image/image.h"

namespace ddhgs::app {
namespace fs = std::filesystem;

namespace {

constexpr double kOrthoNodata = -9999;
using eval::kOrthoCoveredAlpha;

// values [H, W, B] where covered, kOrthoNodata elsewhere.
torch::Tensor with_nodata(const torch::Tensor& values, const torch::Tensor& covered) {
  return torch::where(covered.unsqueeze(2), values, torch::full({}, float(kOrthoNodata)));
}

// A preview: picture [H, W, 3] in [0, 1] with uncovered pixels mid grey.
void write_ortho_preview(const fs::path& path, const torch::Tensor& picture,
                         const torch::Tensor& covered) {
  const torch::Tensor shown =
      torch::where(covered.unsqueeze(2), picture, torch::full({}, 0.5f)).clamp(0, 1);
  io::write_png(path, core::to_u8(shown));
}

}  // namespace

int write_orthomosaic(const TrainedRun& run, const OrthoRequest& request) {
  const io::Scene& scene = *run.scene;
  core::require(scene.georef.has_value(), run.root,
                "--ortho needs a georeferenced scene, and neither the run nor its scene (" +
                    scene.root.string() +
                    ") has georef.json (ddhgs process --rig writes it from captures with GPS)");
  const io::Georeference& georef = *scene.georef;
  std::optional<eval::VegetationIndex> index;
  torch::Tensor index_map;
  if (!request.index.empty()) {
    index = eval::find_vegetation_index(request.index, "--index");
    try {
      index_map = eval::index_band_map(*index, scene.wavelengths_nm);
    } catch (const core::Error& e) {
      throw core::Error(std::string("--index ") + e.what());
    }
  }
  const eval::BandSelection bands =
      eval::select_bands("", request.band_range, scene.wavelengths_nm);
  const fs::path out_dir = request.out.empty() ? run.root / "renders" / "ortho" : request.out;

  const eval::Ground ground = eval::model_ground(run.gaussians, georef);
  const eval::OrthoGrid grid = eval::flight_grid(scene, georef, ground, request.gsd_m);
  core::log_info("ortho: " + std::to_string(grid.width) + " x " + std::to_string(grid.height) +
                 " px at " + core::format_g(grid.gsd_m) +
                 " m (EPSG:" + std::to_string(georef.epsg) + "), ground at " +
                 core::format_g(ground.height_m) + " m, relief " + core::format_g(ground.relief_m) +
                 " m; tiles seen from far above: parallax under " +
                 core::format_g(eval::kOrthoParallaxPx) + " px");
  const eval::Orthomosaic mosaic =
      eval::render_orthomosaic(run.gaussians, georef, grid, ground, run.background);
  const torch::Tensor covered = mosaic.alpha >= float(kOrthoCoveredAlpha);
  // What the model shows straight down, over its background as in every
  // render (eval/orthomosaic.h says why not the Gaussians' colour alone).
  const torch::Tensor& reflectance = mosaic.image;
  const double covered_fraction = covered.to(torch::kFloat64).mean().item<double>();

  io::GeoRaster raster;
  raster.epsg = georef.epsg;
  const std::vector<double> gt = grid.geotransform();
  for (int i = 0; i < 6; ++i) raster.geotransform[size_t(i)] = gt[size_t(i)];
  raster.nodata = kOrthoNodata;
  std::string name;
  int files = 0;
  io::FolderLock lock(run.root, "render");
  io::OutputRequest output{out_dir, io::OutputKind::Renders, true, {run.root, scene.root}, ""};
  output.merge = true;
  io::write_into_folder_atomically(output, [&](const fs::path& tmp) {
    if (index) {
      name = index->name;
      const torch::Tensor values = eval::index_values(reflectance, index_map);  // [H, W]
      const torch::Tensor valid = covered & values.isfinite();
      raster.bands = with_nodata(values.unsqueeze(2), valid);
      raster.descriptions = {index->name + " (" + index->a.name + " - " + index->b.name + ") / (" +
                             index->a.name + " + " + index->b.name + ")"};
      io::write_cog(tmp / (name + ".tif"), raster);
      write_ortho_preview(tmp / (name + ".png"), eval::index_picture(values.nan_to_num(0)), valid);
    } else {
      name = bands.pseudo_rgb ? "reflectance" : "reflectance_" + bands.label;
      const int64_t first = bands.pseudo_rgb ? 0 : bands.first;
      const int64_t last = bands.pseudo_rgb ? scene.bands() - 1 : bands.last;
      raster.bands = with_nodata(reflectance.slice(2, first, last + 1), covered);
      for (int64_t b = first; b <= last; ++b) {
        raster.wavelengths_nm.push_back(scene.wavelengths_nm[size_t(b)]);
        raster.descriptions.push_back(core::format_g(scene.wavelengths_nm[size_t(b)]) + " nm");
      }
      io::write_cog(tmp / (name + ".tif"), raster);
      const torch::Tensor picture = eval::picture(reflectance.clamp(0, 1), scene.wavelengths_nm,
                                                  bands, eval::Colormap::Viridis);
      write_ortho_preview(tmp / (name + ".png"), picture, covered);
    }
    const nlohmann::json record = {{"epsg", georef.epsg},
                                   {"geotransform", gt},
                                   {"width", grid.width},
                                   {"height", grid.height},
                                   {"gsd_m", grid.gsd_m},
                                   {"ground_height_m", ground.height_m},
                                   {"relief_m", ground.relief_m},
                                   {"parallax_bound_px", eval::kOrthoParallaxPx},
                                   {"covered_fraction", covered_fraction},
                                   {"nodata", kOrthoNodata},
                                   {"covered_alpha", kOrthoCoveredAlpha}};
    io::write_file_atomically(tmp / (name + ".json"), record.dump(2) + "\n");
    files = 3;
  });
  std::cout << "orthomosaic " << name << ": " << grid.width << " x " << grid.height << " px, "
            << core::format_g(grid.gsd_m) << " m, EPSG:" << georef.epsg << ", "
            << int(std::lround(100 * covered_fraction)) << " % covered -> "
            << (out_dir / (name + ".tif")).string() << "\n";
  return files;
}

}  // namespace ddhgs::app
