// Multispectral rig captures as they come off the camera: one single-band
// TIFF per band camera per trigger, described by the XMP metadata the rig
// writes into each file (MicaSense RedEdge / Altum layout: Camera:BandName,
// Camera:CentralWavelength, Camera:RigCameraIndex, MicaSense:CaptureId, ...).
//
// This is the reading and checking half of issue 31: which band each file
// holds, through which camera, in which capture. Radiometry (EXIF exposure,
// gain, black level) and placing the band cameras in a scene are not here yet.
#pragma once
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace ddhgs::io {

// One band image and what its XMP says about it.
struct RigBandImage {
  std::filesystem::path file;
  std::string capture_id;                  // MicaSense:CaptureId: the files of one trigger
  int rig_index = 0;                       // Camera:RigCameraIndex (1-based on MicaSense rigs)
  std::string band_name;                   // Camera:BandName, e.g. "Red edge"
  double centre_nm = 0;                    // Camera:CentralWavelength
  double fwhm_nm = 0;                      // Camera:WavelengthFWHM
  double focal_length_mm = 0;              // Camera:PerspectiveFocalLength (0: absent)
  std::vector<double> principal_point_mm;  // Camera:PrincipalPoint "x,y" (empty: absent)
  std::vector<double> distortion;          // Camera:PerspectiveDistortion k1 k2 k3 p1 p2
  // Camera:RigRelatives: this camera's rotation against the rig's reference
  // camera, three angles in degrees as the file gives them (empty: absent).
  std::vector<double> rig_relatives_deg;
  int64_t width = 0, height = 0;
  int bits = 0;  // bits per sample
};

// A property of an XMP packet, in either form XMP allows: an attribute
// (ns:Name="value") or an element (<ns:Name>value</ns:Name>), any namespace
// prefix. nullopt when absent.
std::optional<std::string> xmp_property(const std::string& xmp, const std::string& name);
// The items of a property: an rdf:Seq / rdf:Bag of rdf:li, or a comma-separated
// value. Empty when absent.
std::vector<std::string> xmp_list(const std::string& xmp, const std::string& name);

// Reads one band image's metadata (not its pixels). core::Error naming the
// file when it is not a single-band TIFF, has no XMP, or its XMP lacks the
// band (a rig this reader does not know is named as such).
RigBandImage read_rig_band_image(const std::filesystem::path& file);

// The band images of one trigger, by rig index.
struct RigCapture {
  std::string id;
  std::vector<RigBandImage> bands;
};

// Every .tif/.tiff under dir (any depth), grouped into captures and checked:
// every capture holds the same band cameras (one missing is named, with its
// capture), no camera twice in a capture, and the files named like one
// capture (IMG_0007_1.tif ... IMG_0007_5.tif) belong to one capture id.
// Captures come in file-name order. core::Error naming the file otherwise.
std::vector<RigCapture> read_rig_captures(const std::filesystem::path& dir);

// True when dir holds TIFF files (any depth) but no transforms.json or COLMAP
// model at its top: a folder of rig captures rather than a scene.
bool looks_like_rig_captures(const std::filesystem::path& dir);

// The rotation angle, degrees, of a band camera against the reference camera
// from its three rig-relative angles (composed about x, y and z).
double rig_relative_angle_deg(const std::vector<double>& angles_deg);

}  // namespace ddhgs::io
