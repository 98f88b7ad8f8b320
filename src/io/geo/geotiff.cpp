#include "io/geo/geotiff.h"

#include <cpl_conv.h>
#include <cpl_error.h>
#include <cpl_string.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <memory>
#include <mutex>

#include "core/error.h"
#include "io/files/atomic_file.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

struct DatasetCloser {
  void operator()(GDALDataset* d) const { GDALClose(d); }
};
using GdalDataset = std::unique_ptr<GDALDataset, DatasetCloser>;

// GDAL's last error as the end of a sentence.
std::string gdal_error() {
  const char* message = CPLGetLastErrorMsg();
  return message && *message ? std::string(": ") + message : std::string();
}

// The raster in memory, every band and its description, nodata and
// wavelength set, ready for the COG driver to copy.
GdalDataset memory_dataset(const GeoRaster& r, const fs::path& path) {
  const int height = int(r.bands.size(0)), width = int(r.bands.size(1)),
            count = int(r.bands.size(2));
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  core::require(mem != nullptr, path, "GDAL has no MEM driver");
  GdalDataset d(mem->Create("", width, height, count, GDT_Float32, nullptr));
  core::require(d != nullptr, path, "GDAL cannot hold the raster in memory" + gdal_error());
  OGRSpatialReference srs;
  core::require(srs.importFromEPSG(r.epsg) == OGRERR_NONE, path,
                "GDAL does not know EPSG:" + std::to_string(r.epsg) + gdal_error());
  core::require(d->SetSpatialRef(&srs) == CE_None, path, "cannot set the CRS" + gdal_error());
  double gt[6];
  for (int i = 0; i < 6; ++i) gt[i] = r.geotransform[size_t(i)];
  core::require(d->SetGeoTransform(gt) == CE_None, path, "cannot set the geotransform");
  const torch::Tensor data = r.bands.to(torch::kFloat32).contiguous();
  // [H, W, B] interleaved: one call writes every band.
  const CPLErr written =
      d->RasterIO(GF_Write, 0, 0, width, height, data.data_ptr<float>(), width, height, GDT_Float32,
                  count, nullptr, GSpacing(sizeof(float)) * count,
                  GSpacing(sizeof(float)) * count * width, GSpacing(sizeof(float)), nullptr);
  core::require(written == CE_None, path, "cannot fill the raster" + gdal_error());
  for (int b = 0; b < count; ++b) {
    GDALRasterBand* band = d->GetRasterBand(b + 1);
    band->SetDescription(r.descriptions.at(size_t(b)).c_str());
    band->SetNoDataValue(r.nodata);
    if (!r.wavelengths_nm.empty()) {
      // GDAL's imagery metadata (micrometres) and the ENVI-style pair.
      const std::string nm = CPLSPrintf("%.10g", r.wavelengths_nm[size_t(b)]);
      band->SetMetadataItem("CENTRAL_WAVELENGTH_UM",
                            CPLSPrintf("%.10g", r.wavelengths_nm[size_t(b)] / 1000), "IMAGERY");
      band->SetMetadataItem("wavelength", nm.c_str());
      band->SetMetadataItem("wavelength_units", "nm");
    }
  }
  return d;
}

}  // namespace

void write_cog(const fs::path& path, const GeoRaster& r) {
  core::require(
      r.bands.defined() && r.bands.dim() == 3 && r.bands.size(2) > 0 &&
          int64_t(r.descriptions.size()) == r.bands.size(2) &&
          (r.wavelengths_nm.empty() || int64_t(r.wavelengths_nm.size()) == r.bands.size(2)),
      path, "a GeoTIFF needs [H, W, B] bands and one description per band");
  static std::once_flag registered;
  std::call_once(registered, [] { GDALAllRegister(); });
  CPLErrorReset();
  const GdalDataset source = memory_dataset(r, path);
  GDALDriver* cog = GetGDALDriverManager()->GetDriverByName("COG");
  core::require(cog != nullptr, path, "this GDAL has no COG driver (GDAL 3.1 or newer)");
  write_atomically(path, [&](const fs::path& tmp) {
    CPLStringList options;
    options.SetNameValue("COMPRESS", "DEFLATE");
    options.SetNameValue("PREDICTOR", "YES");  // floating-point predictor for float32
    options.SetNameValue("BLOCKSIZE", "512");
    options.SetNameValue("OVERVIEWS", "AUTO");
    options.SetNameValue("NUM_THREADS", "1");
    GdalDataset out(
        cog->CreateCopy(tmp.c_str(), source.get(), FALSE, options.List(), nullptr, nullptr));
    if (!out) throw core::Error(path, "GDAL could not write the GeoTIFF" + gdal_error());
    out->FlushCache();
    if (CPLGetLastErrorType() == CE_Failure)
      throw core::Error(path, "GDAL could not write the GeoTIFF" + gdal_error());
  });
}

}  // namespace ddhgs::io
