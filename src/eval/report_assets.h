// The static files of a report page (page template, scripts, style, and the
// vendored uPlot and PlayCanvas libraries with their licences), carried
// inside the binary: the definition is generated from the files listed in
// web/assets.cmake at build time (cmake/embed.cmake).
#pragma once
#include <string>
#include <vector>

namespace ddhgs::eval {

struct ReportAsset {
  std::string name;      // "index.html", or a file name under REPORT/assets/
  std::string source;    // where it comes from in the source tree, e.g. "web/report/report.js"
  std::string contents;  // UTF-8 text
};

const std::vector<ReportAsset>& report_assets();

}  // namespace ddhgs::eval
