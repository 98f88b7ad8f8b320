// `ddhgs render RUN --ortho`: the run's Gaussians straight down over its
// flight's footprint (eval/orthomosaic.h), as Cloud-Optimised GeoTIFFs in
// the scene's projected CRS (io/geo/geotiff.h) with PNG previews.
#pragma once
#include <filesystem>
#include <string>

#include "app/trained_run.h"

namespace ddhgs::app {

struct OrthoRequest {
  double gsd_m = 0;           // 0: the flight's own
  std::string index;          // "ndvi", "ndre", "gndvi", or empty: reflectance
  std::string band_range;     // "MIN:MAX" nm, or empty: every band
  std::filesystem::path out;  // empty: RUN/renders/ortho
};

// Checks everything it can before rendering (the run's georeference, the
// index's bands, the range); core::Error otherwise, and nothing is written.
// Returns the number of files written.
int write_orthomosaic(const TrainedRun& run, const OrthoRequest& request);

}  // namespace ddhgs::app
