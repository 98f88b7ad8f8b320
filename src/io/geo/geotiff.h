// Georeferenced rasters as Cloud-Optimised GeoTIFFs, written through GDAL's
// COG driver: float32 bands, tiled (512 px), DEFLATE with the floating-point
// predictor, overviews, the CRS by EPSG code and a north-up geotransform,
// each band's description (e.g. "668 nm") and nodata value. GIS software
// (QGIS, ArcGIS, gdalinfo) reads them as they are.
#pragma once
#include "core/tensor.h"

#include <array>
#include <filesystem>
#include <string>
#include <vector>

namespace ddhgs::io {

struct GeoRaster {
  torch::Tensor bands;                    // [H, W, B] float32; nodata where nothing was seen
  std::vector<std::string> descriptions;  // B band descriptions
  std::vector<double> wavelengths_nm;     // B, or empty (an index map)
  double nodata = -9999;
  int epsg = 0;
  // GDAL's: left edge, pixel width, 0, top edge, 0, -pixel height (CRS units).
  std::array<double, 6> geotransform{};
};

// Written to a temporary sibling and renamed (nothing half-written is left).
// core::Error naming path when GDAL cannot write it or does not know the EPSG
// code.
void write_cog(const std::filesystem::path& path, const GeoRaster& raster);

}  // namespace ddhgs::io
