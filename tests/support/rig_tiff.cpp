#include "support/rig_tiff.h"

#include <cstdio>

#include "io/rig/rig_capture.h"

namespace ddhgs::test {

std::string rig_xmp(const RigBandSpec& s) {
  char head[1024];
  std::snprintf(head, sizeof head,
                "<x:xmpmeta xmlns:x=\"adobe:ns:meta/\"><rdf:RDF "
                "xmlns:rdf=\"http://www.w3.org/1999/02/22-rdf-syntax-ns#\">\n"
                "<rdf:Description rdf:about=\"\" xmlns:Camera=\"http://pix4d.com/camera/1.0/\"\n"
                " xmlns:MicaSense=\"http://micasense.com/MicaSense/1.0/\"\n"
                " Camera:BandName=\"%s\" Camera:CentralWavelength=\"%g\"\n"
                " Camera:WavelengthFWHM=\"%g\" Camera:RigCameraIndex=\"%d\"\n"
                " Camera:PerspectiveFocalLength=\"5.4\" Camera:PerspectiveFocalLengthUnits=\"mm\"\n"
                " Camera:PrincipalPoint=\"2.4,1.8\"\n"
                " MicaSense:CaptureId=\"%s\" Camera:RigRelatives=\"%s\">\n",
                s.band.c_str(), s.centre_nm, s.fwhm_nm, s.rig_index, s.capture_id.c_str(),
                s.rig_relatives.c_str());
  return std::string(head) +
         "<Camera:PerspectiveDistortion><rdf:Seq><rdf:li>-0.1</rdf:li><rdf:li>0.2</rdf:li>"
         "<rdf:li>-0.05</rdf:li><rdf:li>0.001</rdf:li><rdf:li>-0.002</rdf:li></rdf:Seq>"
         "</Camera:PerspectiveDistortion>\n</rdf:Description></rdf:RDF></x:xmpmeta>";
}

void write_band_tiff(const std::filesystem::path& path, const std::string& xmp) {
  const torch::Tensor y = torch::arange(12, torch::kInt32).unsqueeze(1);
  const torch::Tensor x = torch::arange(16, torch::kInt32).unsqueeze(0);
  io::write_band_tiff(path, 100 * x + y, xmp);
}

void write_rig_capture(const std::filesystem::path& dir, int number) {
  const RigBandSpec bands[] = {{"", 1, "Blue", 475, 32, "0,0,0"},
                               {"", 2, "Green", 560, 27, "0.5,-0.2,0.1"},
                               {"", 3, "Red", 668, 14, "1.5,0,0"}};
  char stem[32];
  std::filesystem::create_directories(dir);
  for (RigBandSpec band : bands) {
    band.capture_id = "capture" + std::to_string(number);
    std::snprintf(stem, sizeof stem, "IMG_%04d_%d.tif", number, band.rig_index);
    write_band_tiff(dir / stem, rig_xmp(band));
  }
}

}  // namespace ddhgs::test
