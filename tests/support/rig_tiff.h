// Writes band images shaped like a MicaSense rig's: a single-band 16-bit
// TIFF whose XMP packet carries the band and camera properties.
#pragma once
#include <filesystem>
#include <string>

namespace ddhgs::test {

struct RigBandSpec {
  std::string capture_id;
  int rig_index = 1;
  std::string band = "Blue";
  double centre_nm = 475, fwhm_nm = 32;
  std::string rig_relatives = "0,0,0";  // as the file gives them
};

// The XMP packet of one band image (rdf:Description attributes and Seq
// elements, as MicaSense writes them).
std::string rig_xmp(const RigBandSpec& spec);

// A 16 x 12 uint16 TIFF holding `xmp` (none when empty), written by
// io::write_band_tiff; pixel (x, y) holds 100 x + y.
void write_band_tiff(const std::filesystem::path& path, const std::string& xmp);

// The files of a capture (DIR made if needed): DIR/IMG_<number>_<rig index>.tif for each band of a
// 3-camera rig (Blue 475, Green 560, Red 668), capture id "capture<number>".
void write_rig_capture(const std::filesystem::path& dir, int number);

}  // namespace ddhgs::test
