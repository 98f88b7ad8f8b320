// Multispectral rig captures as they come off the camera: one single-band
// TIFF per band camera per trigger, described by the XMP metadata the rig
// writes into each file (MicaSense RedEdge / Altum layout: Camera:BandName,
// Camera:CentralWavelength, Camera:RigCameraIndex, MicaSense:CaptureId, ...).
//
// Which band each file holds, through which camera, in which capture, and
// the radiometric metadata (EXIF exposure, gain, black level; XMP
// calibration, vignetting, DLS irradiance) that io/rig/rig_radiometry.h turns
// into radiance and reflectance. Every value the radiometry or the geometry
// uses is range-checked as the file is read (one error naming the file, the
// tag and the value). process/rig.h places the band cameras in a scene.
#pragma once
#include "core/tensor.h"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"

namespace ddhgs::io {

// What a band image's metadata says about turning its counts into radiance
// (MicaSense's published model; see io/rig/rig_radiometry.h). Each field is
// empty or 0 when the file does not give it.
struct RigRadiometry {
  double black_level = 0;                    // EXIF BlackLevel (the mean of its values)
  bool has_black_level = false;              // the tag was present
  double exposure_s = 0;                     // EXIF ExposureTime, seconds
  double iso_speed = 0;                      // EXIF ISOSpeed (or ISOSpeedRatings); gain = ISO / 100
  std::vector<double> calibration;           // XMP RadiometricCalibration a1, a2, a3
  std::vector<double> vignetting_centre_px;  // XMP VignettingCenter x, y
  std::vector<double> vignetting_polynomial;  // XMP VignettingPolynomial k0, k1, ...
  // Downwelling light sensor, W/m^2/nm on level ground, as the camera maker
  // defines it: a DLS 2's HorizontalIrradiance; a DLS 1's SpectralIrradiance
  // (else Irradiance) corrected for the sun's angle to the tilted sensor
  // (io/rig/sun.h) where the file gives the time, the position and the
  // sensor's attitude, else as measured. irradiance_tag names the tag read,
  // irradiance_raw its value (after IrradianceScaleToSIUnits),
  // irradiance_correction what was applied.
  double irradiance = 0;
  double irradiance_raw = 0;
  std::string irradiance_tag;
  std::string irradiance_correction;

  double gain() const { return iso_speed / 100; }
};

// One band image and what its XMP and EXIF say about it.
struct RigBandImage {
  std::filesystem::path file;
  std::string capture_id;      // MicaSense:CaptureId: the files of one trigger
  int rig_index = 0;           // Camera:RigCameraIndex (1-based on MicaSense rigs)
  std::string band_name;       // Camera:BandName, e.g. "Red edge"
  double centre_nm = 0;        // Camera:CentralWavelength
  double fwhm_nm = 0;          // Camera:WavelengthFWHM
  double focal_length_mm = 0;  // Camera:PerspectiveFocalLength (0: absent)
  // Its unit, "mm" or "px" (focal_length_mm then holds pixels): the
  // PerspectiveFocalLengthUnits tag; without it (older firmware writes pixels
  // and no tag) the reading that agrees with EXIF FocalLength, else pixels
  // unless the value is too short to be pixels. focal_units_from says which.
  std::string focal_length_units = "mm";
  std::string focal_units_from = "tag";
  double exif_focal_length_mm = 0;         // EXIF FocalLength (0: absent)
  double px_per_mm = 0;                    // EXIF FocalPlaneXResolution (pixels per mm; 0: absent)
  std::vector<double> principal_point_mm;  // Camera:PrincipalPoint "x,y" (empty: absent)
  std::vector<double> distortion;          // Camera:PerspectiveDistortion k1 k2 k3 p1 p2
  // Camera:RigRelatives: this camera's rotation against the rig's reference
  // camera, three angles in degrees as the file gives them (empty: absent).
  std::vector<double> rig_relatives_deg;
  int64_t width = 0, height = 0;
  int bits = 0;  // bits per sample
  RigRadiometry radiometry;
  // Where and when: EXIF GPS (degrees, metres) and DateTimeOriginal +
  // SubSecTime (UTC, as MicaSense cameras write it), seconds since 1970.
  bool has_position = false;
  double latitude_deg = 0, longitude_deg = 0, altitude_m = 0;
  bool has_time = false;
  double utc_seconds = 0;
  // The DLS's attitude (XMP DLS:Yaw, Pitch, Roll, radians); empty: absent.
  std::vector<double> dls_pose_rad;
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
// band (a rig this reader does not know is named as such), or when a value
// the radiometry or geometry uses is out of range (a wavelength, bandwidth,
// calibration coefficient, vignetting polynomial that turns negative, black
// level, exposure, gain, irradiance, focal length, principal point, rig
// angle, position): the error names the tag and the value.
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

// The band camera's pinhole intrinsics and lens distortion in pixels, from
// its focal length, principal point (mm, through the focal-plane resolution)
// and PerspectiveDistortion (k1, k2, k3, p1, p2). core::Error naming the file
// when the focal length or the resolution it needs is absent.
core::Intrinsics rig_intrinsics(const RigBandImage& image);

// The band camera's rotation against the rig's reference camera from its
// RigRelatives (x, y, z angles in degrees): Rz * Ry * Rx, taking a direction
// in the reference camera's axes to this camera's. Identity when absent.
core::Mat3 rig_relative_rotation(const std::vector<double>& angles_deg);

// Writes image.file as a rig band image: a single-band 16-bit TIFF of
// `counts` ([H, W], rounded and clamped to 0..65535) whose XMP and EXIF carry
// every field of `image` in the MicaSense layout this file reads (the
// irradiance under image.radiometry.irradiance_tag, SpectralIrradiance when
// empty, with IrradianceScaleToSIUnits 1). For synthetic rig captures and
// tests. core::Error naming the file when it cannot be written.
void write_rig_band_image(const RigBandImage& image, const torch::Tensor& counts);

// Writes `path` as a single-band 16-bit TIFF of counts ([H, W]) carrying
// `xmp` as it is (none when empty) and no EXIF: a band image with whatever
// metadata a test or a conversion hands it.
void write_band_tiff(const std::filesystem::path& path, const torch::Tensor& counts,
                     const std::string& xmp);

// The rotation angle, degrees, of a band camera against the reference camera
// from its three rig-relative angles (composed about x, y and z).
double rig_relative_angle_deg(const std::vector<double>& angles_deg);

}  // namespace ddhgs::io
