#include "io/rig/rig_capture.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <map>
#include <set>
#include <utility>

#include "core/error.h"
#include "core/text.h"
#include "io/cube/tiff_open.h"
#include "io/rig/sun.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

bool name_char(char c) {
  return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.';
}

std::string unescape(std::string s) {
  static const std::pair<const char*, const char*> entities[] = {
      {"&lt;", "<"}, {"&gt;", ">"}, {"&quot;", "\""}, {"&apos;", "'"}, {"&amp;", "&"}};
  for (const auto& [from, to] : entities)
    for (size_t at = s.find(from); at != std::string::npos; at = s.find(from, at + 1))
      s.replace(at, std::string(from).size(), to);
  return s;
}

using core::trim;

// Where ":name" follows a namespace prefix (letters right before the colon,
// and before them a tag or attribute boundary), from `from` on.
size_t find_qualified(const std::string& xmp, const std::string& name, size_t from,
                      size_t* prefix_start) {
  const std::string key = ":" + name;
  for (size_t at = xmp.find(key, from); at != std::string::npos; at = xmp.find(key, at + 1)) {
    const size_t end = at + key.size();
    if (end < xmp.size() && name_char(xmp[end])) continue;  // a longer name
    size_t p = at;
    while (p > 0 && name_char(xmp[p - 1])) --p;
    if (p == at || p == 0) continue;
    const char before = xmp[p - 1];
    if (before != '<' && !std::isspace(static_cast<unsigned char>(before))) continue;
    *prefix_start = p;
    return at;
  }
  return std::string::npos;
}

// The element form's inner text, raw: <ns:name ...>INNER</ns:name>.
std::optional<std::string> element_inner(const std::string& xmp, const std::string& name) {
  size_t p = 0;
  for (size_t at = find_qualified(xmp, name, 0, &p); at != std::string::npos;
       at = find_qualified(xmp, name, at + 1, &p)) {
    if (xmp[p - 1] != '<') continue;
    const std::string tag = xmp.substr(p, at + 1 + name.size() - p);  // "ns:name"
    const size_t open_end = xmp.find('>', at);
    if (open_end == std::string::npos) return std::nullopt;
    if (xmp[open_end - 1] == '/') return std::string();  // <ns:name/>
    const size_t close = xmp.find("</" + tag, open_end);
    if (close == std::string::npos) return std::nullopt;
    return xmp.substr(open_end + 1, close - open_end - 1);
  }
  return std::nullopt;
}

std::optional<std::string> attribute(const std::string& xmp, const std::string& name) {
  size_t p = 0;
  for (size_t at = find_qualified(xmp, name, 0, &p); at != std::string::npos;
       at = find_qualified(xmp, name, at + 1, &p)) {
    if (xmp[p - 1] == '<') continue;  // an element
    size_t q = at + 1 + name.size();
    while (q < xmp.size() && std::isspace(static_cast<unsigned char>(xmp[q]))) ++q;
    if (q >= xmp.size() || xmp[q] != '=') continue;
    ++q;
    while (q < xmp.size() && std::isspace(static_cast<unsigned char>(xmp[q]))) ++q;
    if (q >= xmp.size() || (xmp[q] != '"' && xmp[q] != '\'')) continue;
    const size_t close = xmp.find(xmp[q], q + 1);
    if (close == std::string::npos) return std::nullopt;
    return unescape(xmp.substr(q + 1, close - q - 1));
  }
  return std::nullopt;
}

double number(const std::string& text, const fs::path& file, const std::string& what) {
  const std::string t = trim(text);
  char* end = nullptr;
  const double v = std::strtod(t.c_str(), &end);
  if (t.empty() || end != t.c_str() + t.size() || !std::isfinite(v))
    throw core::Error(file, "XMP " + what + " is '" + t + "', not a number");
  return v;
}

std::vector<double> numbers(const std::vector<std::string>& items, const fs::path& file,
                            const std::string& what) {
  std::vector<double> out;
  for (const std::string& item : items) out.push_back(number(item, file, what));
  return out;
}

bool is_tiff(const fs::path& path) {
  const std::string ext = core::lower(path.extension().string());
  return ext == ".tif" || ext == ".tiff";
}

// "IMG_0007_3" -> "IMG_0007": the files a rig names as one capture.
std::string capture_stem(const fs::path& file) {
  const std::string stem = file.stem().string();
  const size_t underscore = stem.rfind('_');
  return underscore == std::string::npos ? stem : stem.substr(0, underscore);
}

// A rational or float tag of the current directory, whichever width this
// libtiff hands it back in (EXIF rationals come back as float). 0 if absent.
double real_tag(TIFF* tif, uint32_t tag) {
  const TIFFField* field = TIFFFieldWithTag(tif, tag);
  if (!field) return 0;
  if (TIFFFieldSetGetSize(field) == 8) {
    double value = 0;
    return TIFFGetField(tif, tag, &value) == 1 ? value : 0;
  }
  float value = 0;
  return TIFFGetField(tif, tag, &value) == 1 ? value : 0;
}

// An ASCII tag of the current directory ("" if absent).
std::string text_tag(TIFF* tif, uint32_t tag) {
  const char* value = nullptr;
  return TIFFGetField(tif, tag, &value) == 1 && value ? std::string(value) : std::string();
}

// "2017:10:19 20:40:39" and sub-seconds "200173789" as UTC seconds since
// 1970; false when the text is not such a time.
bool exif_time(const std::string& text, const std::string& subsec, double* seconds) {
  std::tm t{};
  if (std::sscanf(text.c_str(), "%d:%d:%d %d:%d:%d", &t.tm_year, &t.tm_mon, &t.tm_mday, &t.tm_hour,
                  &t.tm_min, &t.tm_sec) != 6 ||
      t.tm_year < 1970 || t.tm_mon < 1 || t.tm_mon > 12 || t.tm_mday < 1 || t.tm_mday > 31)
    return false;
  t.tm_year -= 1900;
  t.tm_mon -= 1;
  *seconds = double(timegm(&t));
  const std::string digits = trim(subsec);
  if (!digits.empty() && digits.find_first_not_of("0123456789") == std::string::npos)
    *seconds += std::strtod(("0." + digits).c_str(), nullptr);
  return true;
}

// A rational array tag of the GPS directory (degrees, minutes, seconds), in
// whichever width this libtiff hands it back.
bool gps_triple(TIFF* tif, uint32_t tag, double out[3]) {
  const TIFFField* field = TIFFFieldWithTag(tif, tag);
  if (!field) return false;
  void* values = nullptr;
  if (TIFFGetField(tif, tag, &values) != 1 || !values) return false;
  for (int i = 0; i < 3; ++i)
    out[i] = TIFFFieldSetGetSize(field) == 8 ? static_cast<const double*>(values)[i]
                                             : double(static_cast<const float*>(values)[i]);
  return true;
}

// The GPS directory: latitude, longitude (signed by their references) and
// altitude. Leaves the handle in the GPS directory.
void read_gps(TIFF* tif, uint64_t offset, RigBandImage* image) {
  if (offset == 0 || TIFFReadGPSDirectory(tif, offset) != 1) return;
  double lat[3], lon[3];
  if (!gps_triple(tif, GPSTAG_LATITUDE, lat) || !gps_triple(tif, GPSTAG_LONGITUDE, lon)) return;
  image->latitude_deg = lat[0] + lat[1] / 60 + lat[2] / 3600;
  image->longitude_deg = lon[0] + lon[1] / 60 + lon[2] / 3600;
  if (core::lower(text_tag(tif, GPSTAG_LATITUDEREF)) == "s") image->latitude_deg *= -1;
  if (core::lower(text_tag(tif, GPSTAG_LONGITUDEREF)) == "w") image->longitude_deg *= -1;
  image->altitude_m = real_tag(tif, GPSTAG_ALTITUDE);
  uint8_t below_sea_level = 0;
  if (TIFFGetField(tif, GPSTAG_ALTITUDEREF, &below_sea_level) == 1 && below_sea_level == 1)
    image->altitude_m *= -1;
  image->has_position = true;
}

// EXIF: BlackLevel in the main directory (a DNG tag, as MicaSense writes
// it), ExposureTime, ISOSpeed, FocalLength, FocalPlaneXResolution and the
// time in the EXIF directory, the position in the GPS directory.
void read_exif(TIFF* tif, RigBandImage* image) {
  RigRadiometry* r = &image->radiometry;
  uint16_t count = 0;
  float* levels = nullptr;
  if (TIFFGetField(tif, TIFFTAG_BLACKLEVEL, &count, &levels) == 1 && count > 0 && levels) {
    double sum = 0;
    for (uint16_t i = 0; i < count; ++i) sum += levels[i];
    r->black_level = sum / count;
    r->has_black_level = true;
  }
  uint64_t exif_offset = 0, gps_offset = 0;
  if (TIFFGetField(tif, TIFFTAG_GPSIFD, &gps_offset) != 1) gps_offset = 0;
  if (TIFFGetField(tif, TIFFTAG_EXIFIFD, &exif_offset) != 1 || exif_offset == 0 ||
      TIFFReadEXIFDirectory(tif, exif_offset) != 1) {
    read_gps(tif, gps_offset, image);
    return;
  }
  r->exposure_s = real_tag(tif, EXIFTAG_EXPOSURETIME);
  image->px_per_mm = real_tag(tif, EXIFTAG_FOCALPLANEXRESOLUTION);
  image->exif_focal_length_mm = real_tag(tif, EXIFTAG_FOCALLENGTH);
  image->has_time = exif_time(text_tag(tif, EXIFTAG_DATETIMEORIGINAL),
                              text_tag(tif, EXIFTAG_SUBSECTIME), &image->utc_seconds);
  uint32_t iso = 0;
  if (TIFFGetField(tif, EXIFTAG_ISOSPEED, &iso) == 1 && iso > 0) {
    r->iso_speed = iso;
  } else {
    uint16_t n = 0;
    uint16_t* ratings = nullptr;
    if (TIFFGetField(tif, EXIFTAG_ISOSPEEDRATINGS, &n, &ratings) == 1 && n > 0 && ratings)
      r->iso_speed = ratings[0];
  }
  read_gps(tif, gps_offset, image);
}

// XMP radiometry: calibration, vignetting and the DLS irradiance, scaled to
// W/m^2/nm as MicaSense documents it (IrradianceScaleToSIUnits where given;
// a DLS 2, which writes HorizontalIrradiance, otherwise reports in 1/100).
void read_xmp_radiometry(const std::string& xmp, const fs::path& file, RigRadiometry* r) {
  r->calibration = numbers(xmp_list(xmp, "RadiometricCalibration"), file, "RadiometricCalibration");
  if (!r->calibration.empty() && r->calibration.size() != 3)
    throw core::Error(file, "XMP RadiometricCalibration has " +
                                std::to_string(r->calibration.size()) +
                                " values, expected 3 (a1, a2, a3)");
  r->vignetting_centre_px = numbers(xmp_list(xmp, "VignettingCenter"), file, "VignettingCenter");
  if (!r->vignetting_centre_px.empty() && r->vignetting_centre_px.size() != 2)
    throw core::Error(file, "XMP VignettingCenter has " +
                                std::to_string(r->vignetting_centre_px.size()) +
                                " values, expected 2 (x, y)");
  r->vignetting_polynomial =
      numbers(xmp_list(xmp, "VignettingPolynomial"), file, "VignettingPolynomial");
  const std::optional<std::string> horizontal = xmp_property(xmp, "HorizontalIrradiance");
  double scale = horizontal ? 0.01 : 1.0;
  if (auto s = xmp_property(xmp, "IrradianceScaleToSIUnits"))
    scale = number(*s, file, "IrradianceScaleToSIUnits");
  for (const char* tag : {"HorizontalIrradiance", "SpectralIrradiance", "Irradiance"}) {
    const std::optional<std::string> value = xmp_property(xmp, tag);
    if (!value) continue;
    const double irradiance = number(*value, file, tag) * scale;
    if (irradiance <= 0) continue;  // a DLS that did not measure
    r->irradiance = r->irradiance_raw = irradiance;
    r->irradiance_tag = tag;
    r->irradiance_correction = horizontal ? "none: the sensor reports irradiance on level ground"
                                          : "none: the file lacks the time, position or the "
                                            "sensor's attitude (uncorrected DLS reading)";
    break;
  }
}

// A DLS 1 reading on level ground (io/rig/sun.h), where the file gives what
// the correction needs.
void correct_dls1(RigBandImage* image) {
  RigRadiometry& r = image->radiometry;
  if (r.irradiance_tag == "HorizontalIrradiance" || r.irradiance <= 0 || !image->has_position ||
      !image->has_time || image->dls_pose_rad.size() != 3)
    return;
  const SunPosition sun =
      sun_position(image->latitude_deg, image->longitude_deg, image->utc_seconds);
  const auto to_sun = sun_direction_ned(sun);
  const auto normal =
      sensor_normal_ned(image->dls_pose_rad[0], image->dls_pose_rad[1], image->dls_pose_rad[2]);
  const double cosine = to_sun[0] * normal[0] + to_sun[1] * normal[1] + to_sun[2] * normal[2];
  const double theta = std::acos(std::clamp(cosine, -1.0, 1.0));
  const double level = dls1_horizontal_irradiance(r.irradiance_raw, theta, sun.elevation);
  char note[200];
  if (!(level > 0) || sun.elevation <= 0) {
    std::snprintf(note, sizeof note,
                  "none: the sun stood %.1f deg above the horizon, %.1f deg off the sensor "
                  "(uncorrected DLS reading)",
                  sun.elevation * 180 / 3.14159265358979323846,
                  theta * 180 / 3.14159265358979323846);
    r.irradiance_correction = note;
    return;
  }
  r.irradiance = level;
  std::snprintf(note, sizeof note,
                "DLS 1 to level ground: sun %.2f deg high, %.2f deg off the sensor, Fresnel "
                "transmission %.4f, direct:diffuse 6:1",
                sun.elevation * 180 / 3.14159265358979323846, theta * 180 / 3.14159265358979323846,
                dls_transmission(theta));
  r.irradiance_correction = note;
}

// The focal length's unit where the file has no PerspectiveFocalLengthUnits.
void decide_focal_units(RigBandImage* image) {
  const double f = image->focal_length_mm;
  if (f <= 0) return;
  if (image->exif_focal_length_mm > 0 && image->px_per_mm > 0) {
    const double as_mm = std::abs(f / image->exif_focal_length_mm - 1);
    const double as_px = std::abs(f / (image->exif_focal_length_mm * image->px_per_mm) - 1);
    image->focal_length_units = as_mm < as_px ? "mm" : "px";
    image->focal_units_from = "EXIF FocalLength";
    return;
  }
  // Too short to be pixels (under a tenth of the image's width, a field of
  // view over 157 degrees): millimetres.
  const bool mm = f < 0.1 * double(image->width);
  image->focal_length_units = mm ? "mm" : "px";
  image->focal_units_from = "its size (no units tag, no EXIF FocalLength)";
}

// Every value the radiometry or the geometry uses, in range.
void check_metadata(const RigBandImage& b) {
  auto bad = [&](const std::string& tag, double value, const std::string& why) {
    throw core::Error(b.file, tag + " is " + core::number_text(value) + ": " + why);
  };
  if (!(b.centre_nm >= 100 && b.centre_nm <= 20000))
    bad("XMP CentralWavelength", b.centre_nm, "not a wavelength (expected 100 to 20000 nm)");
  if (!(b.fwhm_nm > 0 && b.fwhm_nm < b.centre_nm))
    bad("XMP WavelengthFWHM", b.fwhm_nm, "not a bandwidth (expected above 0 nm, below the centre)");
  if (b.rig_index > 64) bad("XMP RigCameraIndex", b.rig_index, "not a camera of a rig (0 to 64)");
  if (b.bits < 1 || b.bits > 32)
    bad("TIFF BitsPerSample", b.bits, "not a sensor's bit depth (1 to 32)");
  const RigRadiometry& r = b.radiometry;
  const double full_scale = std::ldexp(1.0, b.bits) - 1;
  if (r.has_black_level && !(r.black_level >= 0 && r.black_level < full_scale))
    bad("EXIF BlackLevel", r.black_level,
        "outside the " + std::to_string(b.bits) + "-bit range (0 to " +
            core::number_text(full_scale - 1) + ")");
  if (r.exposure_s != 0 && !(r.exposure_s > 0 && r.exposure_s <= 60))
    bad("EXIF ExposureTime", r.exposure_s, "not an exposure (above 0, at most 60 s)");
  if (r.iso_speed != 0 && !(r.iso_speed >= 1 && r.iso_speed <= 1e6))
    bad("EXIF ISOSpeed", r.iso_speed, "not a gain (ISO 1 to 1000000)");
  if (r.calibration.size() == 3) {
    if (!(r.calibration[0] > 0))
      bad("XMP RadiometricCalibration a1", r.calibration[0],
          "radiance would be zero or negative (a1 must be above 0)");
    // R(y) = 1 / (1 + a2 y / exposure - a3 y) must stay positive on every row.
    if (r.exposure_s > 0)
      for (double y : {0.0, double(std::max<int64_t>(0, b.height - 1))})
        if (!(1 + r.calibration[1] * y / r.exposure_s - r.calibration[2] * y > 0))
          bad("XMP RadiometricCalibration a2", r.calibration[1],
              "with a3 " + core::number_text(r.calibration[2]) +
                  " the row correction turns negative at row " + core::number_text(y));
  }
  if (r.vignetting_centre_px.size() == 2 && !r.vignetting_polynomial.empty()) {
    const double cx = r.vignetting_centre_px[0], cy = r.vignetting_centre_px[1];
    if (std::abs(cx) > 4.0 * double(b.width) || std::abs(cy) > 4.0 * double(b.height))
      bad("XMP VignettingCenter x", cx, "far outside the image");
    double reach = 0;
    for (double x : {0.0, double(b.width)})
      for (double y : {0.0, double(b.height)}) reach = std::max(reach, std::hypot(x - cx, y - cy));
    // 1 + k0 r + k1 r^2 + ... over the radii the image reaches (every pixel
    // step, or 4,096 steps on an image wider than that).
    const double step = std::max(1.0, reach / 4096);
    for (double radius = 0; radius <= reach + step; radius += step) {
      double poly = 0;
      for (auto k = r.vignetting_polynomial.rbegin(); k != r.vignetting_polynomial.rend(); ++k)
        poly = (poly + *k) * radius;
      if (!(poly + 1 > 0) || !std::isfinite(poly))
        throw core::Error(b.file,
                          "XMP VignettingPolynomial turns the vignetting correction "
                          "negative or infinite at " +
                              core::number_text(radius) +
                              " px from its centre: not a lens's vignetting");
    }
  }
  if (r.irradiance_raw != 0 && !(r.irradiance_raw >= 1e-6 && r.irradiance_raw <= 100))
    bad("XMP " + r.irradiance_tag, r.irradiance_raw,
        "not a spectral irradiance (expected 1e-06 to 100 W/m2/nm)");
  if (b.px_per_mm != 0 && !(b.px_per_mm > 1 && b.px_per_mm < 1e5))
    bad("EXIF FocalPlaneXResolution", b.px_per_mm, "not a sensor's pixels per mm");
  if (b.focal_length_mm != 0) {
    const double px =
        b.focal_length_units == "px" ? b.focal_length_mm : b.focal_length_mm * b.px_per_mm;
    if (!(b.focal_length_mm > 0) ||
        (px > 0 && !(px >= 0.05 * double(b.width) && px <= 100 * double(b.width))))
      bad("XMP PerspectiveFocalLength", b.focal_length_mm,
          "not a focal length for a " + std::to_string(b.width) + " px wide image (" +
              b.focal_length_units + ")");
  }
  if (b.principal_point_mm.size() == 2 && b.px_per_mm > 0) {
    const double x = b.principal_point_mm[0] * b.px_per_mm,
                 y = b.principal_point_mm[1] * b.px_per_mm;
    if (!(x > 0 && x < double(b.width) && y > 0 && y < double(b.height)))
      throw core::Error(b.file, "XMP PrincipalPoint is " +
                                    core::join_numbers(b.principal_point_mm) + " mm (" +
                                    core::number_text(x) + ", " + core::number_text(y) +
                                    " px): not inside the image");
  } else if (!b.principal_point_mm.empty() && b.principal_point_mm.size() != 2) {
    throw core::Error(b.file, "XMP PrincipalPoint has " +
                                  std::to_string(b.principal_point_mm.size()) +
                                  " values, expected 2 (x, y in mm)");
  }
  for (double angle : b.rig_relatives_deg)
    if (!(std::abs(angle) <= 90))
      bad("XMP RigRelatives", angle, "not a rig camera's angle (at most 90 degrees)");
  if (b.has_position && !(std::abs(b.latitude_deg) <= 90 && std::abs(b.longitude_deg) <= 180))
    throw core::Error(b.file, "EXIF GPS position " + core::number_text(b.latitude_deg) + ", " +
                                  core::number_text(b.longitude_deg) + " is not on Earth");
  for (double angle : b.dls_pose_rad)
    if (!(std::abs(angle) <= 7)) bad("XMP DLS attitude", angle, "not an angle in radians");
}

// The rdf:li items of an element's inner text (an rdf:Seq, Bag or Alt);
// none when it holds no list.
std::vector<std::string> list_items(const std::string& inner) {
  std::vector<std::string> items;
  for (size_t at = inner.find("<rdf:li"); at != std::string::npos;
       at = inner.find("<rdf:li", at + 1)) {
    const size_t open_end = inner.find('>', at);
    const size_t close = inner.find("</rdf:li>", open_end);
    if (open_end == std::string::npos || close == std::string::npos) break;
    items.push_back(unescape(trim(inner.substr(open_end + 1, close - open_end - 1))));
  }
  return items;
}

}  // namespace

std::optional<std::string> xmp_property(const std::string& xmp, const std::string& name) {
  if (auto value = attribute(xmp, name)) return value;
  auto inner = element_inner(xmp, name);
  if (!inner) return std::nullopt;
  if (inner->find('<') == std::string::npos) return unescape(trim(*inner));
  // A list of one item is that item (Parrot writes BandName so); a longer
  // one, or another structure, has no single value.
  std::vector<std::string> items = list_items(*inner);
  if (items.size() == 1) return std::move(items.front());
  return std::nullopt;
}

std::vector<std::string> xmp_list(const std::string& xmp, const std::string& name) {
  auto inner = element_inner(xmp, name);
  if (inner && inner->find("<rdf:li") != std::string::npos) return list_items(*inner);
  std::vector<std::string> items;
  const std::optional<std::string> value = xmp_property(xmp, name);
  if (!value) return items;
  for (size_t at = 0;;) {
    const size_t comma = value->find(',', at);
    items.push_back(trim(value->substr(at, comma - at)));
    if (comma == std::string::npos) break;
    at = comma + 1;
  }
  return items;
}

RigBandImage read_rig_band_image(const fs::path& file) {
  std::string error;
  TIFF* tif = open_tiff_quietly(file, "r", &error);
  if (!tif)
    throw core::Error(file, "cannot be read as a TIFF" + (error.empty() ? "" : " (" + error + ")"));
  RigBandImage image;
  image.file = file;
  uint32_t width = 0, height = 0;
  uint16_t bits = 0, samples = 1;
  TIFFGetField(tif, TIFFTAG_IMAGEWIDTH, &width);
  TIFFGetField(tif, TIFFTAG_IMAGELENGTH, &height);
  TIFFGetFieldDefaulted(tif, TIFFTAG_BITSPERSAMPLE, &bits);
  TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLESPERPIXEL, &samples);
  uint32_t xmp_size = 0;
  void* xmp_data = nullptr;
  const bool has_xmp = TIFFGetField(tif, TIFFTAG_XMLPACKET, &xmp_size, &xmp_data) == 1;
  const std::string xmp = has_xmp && xmp_data
                              ? std::string(static_cast<const char*>(xmp_data), xmp_size)
                              : std::string();
  read_exif(tif, &image);
  TIFFClose(tif);
  image.width = width;
  image.height = height;
  image.bits = bits;
  if (samples != 1)
    throw core::Error(file, "has " + std::to_string(samples) +
                                " samples per pixel; a rig band image holds one band");
  if (xmp.empty())
    throw core::Error(file, "has no XMP metadata: not a band image of a multispectral rig");
  // Pix4D's camera XMP names the lens model; MicaSense's files leave it out
  // (perspective).
  if (const auto model = xmp_property(xmp, "ModelType");
      model && core::lower(trim(*model)) != "perspective") {
    const std::optional<std::string> rig = xmp_property(xmp, "RigName");
    throw core::Error(file, "XMP Camera:ModelType is '" + *model + "'" +
                                (rig ? " (a " + *rig + " rig)" : std::string()) +
                                ": this reader knows the perspective lens of the MicaSense "
                                "RedEdge / Altum layout, not a " +
                                *model + " lens");
  }
  const std::optional<std::string> band = xmp_property(xmp, "BandName");
  if (!band)
    throw core::Error(file,
                      "its XMP has no Camera:BandName: a rig this reader does not know (it reads "
                      "the MicaSense RedEdge / Altum layout)");
  image.band_name = *band;
  auto required = [&](const std::string& name) {
    const std::optional<std::string> value = xmp_property(xmp, name);
    if (!value) throw core::Error(file, "its XMP has no " + name);
    return number(*value, file, name);
  };
  image.centre_nm = required("CentralWavelength");
  image.fwhm_nm = required("WavelengthFWHM");
  const double index = required("RigCameraIndex");
  image.rig_index = int(index);
  if (index != double(image.rig_index) || image.rig_index < 0)
    throw core::Error(file,
                      "XMP RigCameraIndex is " + std::to_string(index) + ", not a camera number");
  if (auto id = xmp_property(xmp, "CaptureId")) image.capture_id = *id;
  if (auto f = xmp_property(xmp, "PerspectiveFocalLength"))
    image.focal_length_mm = number(*f, file, "PerspectiveFocalLength");
  if (auto units = xmp_property(xmp, "PerspectiveFocalLengthUnits")) {
    image.focal_length_units = core::lower(trim(*units));
    if (image.focal_length_units != "mm" && image.focal_length_units != "px")
      throw core::Error(file,
                        "XMP PerspectiveFocalLengthUnits is '" + *units + "', expected mm or px");
  }
  if (!xmp_property(xmp, "PerspectiveFocalLengthUnits")) decide_focal_units(&image);
  image.principal_point_mm = numbers(xmp_list(xmp, "PrincipalPoint"), file, "PrincipalPoint");
  image.distortion = numbers(xmp_list(xmp, "PerspectiveDistortion"), file, "PerspectiveDistortion");
  image.rig_relatives_deg = numbers(xmp_list(xmp, "RigRelatives"), file, "RigRelatives");
  if (!image.rig_relatives_deg.empty() && image.rig_relatives_deg.size() != 3)
    throw core::Error(file, "XMP RigRelatives has " +
                                std::to_string(image.rig_relatives_deg.size()) +
                                " values, expected 3 angles");
  read_xmp_radiometry(xmp, file, &image.radiometry);
  if (auto yaw = xmp_property(xmp, "Yaw")) {
    const auto pitch = xmp_property(xmp, "Pitch"), roll = xmp_property(xmp, "Roll");
    if (pitch && roll)
      image.dls_pose_rad = {number(*yaw, file, "DLS Yaw"), number(*pitch, file, "DLS Pitch"),
                            number(*roll, file, "DLS Roll")};
  }
  check_metadata(image);
  correct_dls1(&image);
  return image;
}

bool looks_like_rig_captures(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec) || fs::exists(dir / "transforms.json") ||
      fs::exists(dir / "sparse") || fs::exists(dir / "colmap"))
    return false;
  for (fs::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    if (it.depth() > 3) it.disable_recursion_pending();
    if (it->is_regular_file(ec) && is_tiff(it->path())) return true;
  }
  return false;
}

std::vector<RigCapture> read_rig_captures(const fs::path& dir) {
  std::vector<fs::path> files;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec))
    if (it->is_regular_file(ec) && is_tiff(it->path())) files.push_back(it->path());
  core::require(!files.empty(), dir, "holds no TIFF files of rig captures");
  std::sort(files.begin(), files.end());

  std::vector<RigCapture> captures;
  std::map<std::string, size_t> by_id;
  std::map<fs::path, std::pair<std::string, fs::path>> id_of_stem;  // folder/stem -> id, file
  for (const fs::path& file : files) {
    RigBandImage image = read_rig_band_image(file);
    const fs::path stem = file.parent_path() / capture_stem(file);
    if (image.capture_id.empty()) image.capture_id = stem.string();
    auto [named, fresh] = id_of_stem.emplace(stem, std::make_pair(image.capture_id, file));
    if (!fresh && named->second.first != image.capture_id)
      throw core::Error(file, "is from capture " + image.capture_id + " but " +
                                  named->second.second.filename().string() +
                                  ", named as the same capture, is from " + named->second.first +
                                  ": bands of two captures are mixed");
    auto [slot, added] = by_id.emplace(image.capture_id, captures.size());
    if (added) captures.push_back({image.capture_id, {}});
    RigCapture& capture = captures[slot->second];
    for (const RigBandImage& other : capture.bands)
      if (other.rig_index == image.rig_index)
        throw core::Error(file, "is band camera " + std::to_string(image.rig_index) +
                                    " of capture " + capture.id + ", like " + other.file.string() +
                                    ": one camera twice in a capture");
    capture.bands.push_back(std::move(image));
  }
  // Every capture holds every band camera the rig has: its band name and
  // the first file that shows it, by camera.
  std::map<int, std::pair<std::string, std::string>> cameras;
  for (RigCapture& capture : captures) {
    std::sort(
        capture.bands.begin(), capture.bands.end(),
        [](const RigBandImage& a, const RigBandImage& b) { return a.rig_index < b.rig_index; });
    for (const RigBandImage& band : capture.bands)
      cameras.emplace(band.rig_index,
                      std::make_pair(band.band_name, band.file.filename().string()));
  }
  for (const RigCapture& capture : captures) {
    std::set<int> held;
    for (const RigBandImage& band : capture.bands) held.insert(band.rig_index);
    for (const auto& [index, example] : cameras)
      if (!held.count(index))
        throw core::Error(capture.bands.front().file,
                          "capture " + capture.id + " has no image from band camera " +
                              std::to_string(index) + " (" + example.first + ", e.g. " +
                              example.second + " in another capture): a band is missing");
  }
  return captures;
}

namespace {

std::string seq(const std::string& name, const std::vector<double>& values) {
  if (values.empty()) return "";
  std::string out = "<Camera:" + name + "><rdf:Seq>";
  char item[48];
  for (double v : values) {
    std::snprintf(item, sizeof item, "<rdf:li>%.17g</rdf:li>", v);
    out += item;
  }
  return out + "</rdf:Seq></Camera:" + name + ">\n";
}

std::string xmp_of(const RigBandImage& b) {
  const RigRadiometry& r = b.radiometry;
  auto attribute = [](const std::string& name, const std::string& value) {
    return " " + name + "=\"" + value + "\"\n";
  };
  auto real = [](double v) { return core::join_numbers({v}); };
  std::string out =
      "<x:xmpmeta xmlns:x=\"adobe:ns:meta/\"><rdf:RDF "
      "xmlns:rdf=\"http://www.w3.org/1999/02/22-rdf-syntax-ns#\">\n"
      "<rdf:Description rdf:about=\"\" xmlns:Camera=\"http://pix4d.com/camera/1.0/\"\n"
      " xmlns:MicaSense=\"http://micasense.com/MicaSense/1.0/\"\n";
  out += attribute("Camera:BandName", b.band_name);
  out += attribute("Camera:CentralWavelength", real(b.centre_nm));
  out += attribute("Camera:WavelengthFWHM", real(b.fwhm_nm));
  out += attribute("Camera:RigCameraIndex", std::to_string(b.rig_index));
  if (!b.capture_id.empty()) out += attribute("MicaSense:CaptureId", b.capture_id);
  if (b.focal_length_mm > 0) {
    out += attribute("Camera:PerspectiveFocalLength", real(b.focal_length_mm));
    out += attribute("Camera:PerspectiveFocalLengthUnits", b.focal_length_units);
  }
  if (!b.principal_point_mm.empty())
    out += attribute("Camera:PrincipalPoint", core::join_numbers(b.principal_point_mm));
  if (!b.rig_relatives_deg.empty())
    out += attribute("Camera:RigRelatives", core::join_numbers(b.rig_relatives_deg));
  if (r.irradiance > 0) {
    out += attribute("Camera:" + (r.irradiance_tag.empty() ? std::string("SpectralIrradiance")
                                                           : r.irradiance_tag),
                     real(r.irradiance));
    out += attribute("Camera:IrradianceScaleToSIUnits", "1");
  }
  out += ">\n";
  out += seq("PerspectiveDistortion", b.distortion);
  out += seq("RadiometricCalibration", r.calibration);
  out += seq("VignettingCenter", r.vignetting_centre_px);
  out += seq("VignettingPolynomial", r.vignetting_polynomial);
  return out + "</rdf:Description></rdf:RDF></x:xmpmeta>";
}

// A rational triple of the GPS directory, in the width this libtiff takes.
bool set_gps_triple(TIFF* tif, uint32_t tag, const double values[3]) {
  const TIFFField* field = TIFFFieldWithTag(tif, tag);
  if (!field) return false;
  if (TIFFFieldSetGetSize(field) == 8) return TIFFSetField(tif, tag, values) == 1;
  const float narrow[3] = {float(values[0]), float(values[1]), float(values[2])};
  return TIFFSetField(tif, tag, narrow) == 1;
}

// Degrees as EXIF writes them: whole degrees, whole minutes, seconds.
void degrees_minutes_seconds(double degrees, double out[3]) {
  degrees = std::abs(degrees);
  out[0] = std::floor(degrees);
  out[1] = std::floor((degrees - out[0]) * 60);
  out[2] = ((degrees - out[0]) * 60 - out[1]) * 60;
}

// The GPS directory's position: latitude, longitude and altitude with their
// references, as read_gps reads them.
bool write_gps(TIFF* tif, const RigBandImage& image) {
  double lat[3], lon[3];
  degrees_minutes_seconds(image.latitude_deg, lat);
  degrees_minutes_seconds(image.longitude_deg, lon);
  const uint8_t version[4] = {2, 3, 0, 0};
  return TIFFSetField(tif, GPSTAG_VERSIONID, version) == 1 &&
         TIFFSetField(tif, GPSTAG_LATITUDEREF, image.latitude_deg < 0 ? "S" : "N") == 1 &&
         set_gps_triple(tif, GPSTAG_LATITUDE, lat) &&
         TIFFSetField(tif, GPSTAG_LONGITUDEREF, image.longitude_deg < 0 ? "W" : "E") == 1 &&
         set_gps_triple(tif, GPSTAG_LONGITUDE, lon) &&
         TIFFSetField(tif, GPSTAG_ALTITUDEREF, uint8_t(image.altitude_m < 0 ? 1 : 0)) == 1 &&
         TIFFSetField(tif, GPSTAG_ALTITUDE, std::abs(image.altitude_m)) == 1;
}

// image.file as a single-band 16-bit TIFF of counts, with `xmp` (none when
// empty) and the EXIF image's metadata asks for.
void write_band(const RigBandImage& image, const torch::Tensor& counts, const std::string& xmp) {
  core::require(counts.dim() == 2, image.file, "band counts must be [H, W]");
  const uint32_t height = uint32_t(counts.size(0)), width = uint32_t(counts.size(1));
  const torch::Tensor values =
      counts.to(torch::kDouble).round().clamp(0, 65535).to(torch::kInt32).contiguous();
  const int32_t* v = values.data_ptr<int32_t>();
  std::string error;
  TIFF* tif = open_tiff_quietly(image.file, "w", &error);
  if (!tif)
    throw core::Error(image.file, "cannot be written" + (error.empty() ? "" : " (" + error + ")"));
  const RigRadiometry& r = image.radiometry;
  TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, width);
  TIFFSetField(tif, TIFFTAG_IMAGELENGTH, height);
  TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, uint16_t(16));
  TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, uint16_t(1));
  TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
  TIFFSetField(tif, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
  TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, height);
  if (!xmp.empty()) TIFFSetField(tif, TIFFTAG_XMLPACKET, uint32_t(xmp.size()), xmp.data());
  if (r.has_black_level) {
    const float levels[4] = {float(r.black_level), float(r.black_level), float(r.black_level),
                             float(r.black_level)};
    TIFFSetField(tif, TIFFTAG_BLACKLEVEL, uint16_t(4), levels);
  }
  const bool exif = r.exposure_s > 0 || r.iso_speed > 0 || image.px_per_mm > 0;
  if (exif) TIFFSetField(tif, TIFFTAG_EXIFIFD, uint64_t(0));  // its place; filled in below
  if (image.has_position) TIFFSetField(tif, TIFFTAG_GPSIFD, uint64_t(0));
  std::vector<uint16_t> row(width);
  bool ok = true;
  for (uint32_t y = 0; y < height && ok; ++y) {
    for (uint32_t x = 0; x < width; ++x) row[x] = uint16_t(v[size_t(y) * width + x]);
    ok = TIFFWriteScanline(tif, row.data(), y, 0) == 1;
  }
  ok = ok && TIFFWriteDirectory(tif) == 1;
  uint64_t exif_offset = 0, gps_offset = 0;
  if (ok && exif)
    ok = TIFFCreateEXIFDirectory(tif) == 0 &&
         TIFFSetField(tif, EXIFTAG_EXPOSURETIME, r.exposure_s) == 1 &&
         TIFFSetField(tif, EXIFTAG_ISOSPEED, uint32_t(std::lround(r.iso_speed))) == 1 &&
         (image.px_per_mm <= 0 ||
          (TIFFSetField(tif, EXIFTAG_FOCALPLANEXRESOLUTION, image.px_per_mm) == 1 &&
           TIFFSetField(tif, EXIFTAG_FOCALPLANEYRESOLUTION, image.px_per_mm) == 1 &&
           TIFFSetField(tif, EXIFTAG_FOCALPLANERESOLUTIONUNIT, uint16_t(4)) == 1)) &&
         TIFFWriteCustomDirectory(tif, &exif_offset) == 1;
  if (ok && image.has_position)
    ok = TIFFCreateGPSDirectory(tif) == 0 && write_gps(tif, image) &&
         TIFFWriteCustomDirectory(tif, &gps_offset) == 1;
  if (ok && (exif || image.has_position))
    ok = TIFFSetDirectory(tif, 0) == 1 &&
         (!exif || TIFFSetField(tif, TIFFTAG_EXIFIFD, exif_offset) == 1) &&
         (!image.has_position || TIFFSetField(tif, TIFFTAG_GPSIFD, gps_offset) == 1) &&
         TIFFRewriteDirectory(tif) == 1;
  TIFFClose(tif);
  if (!ok) {
    std::error_code ec;
    fs::remove(image.file, ec);
    throw core::Error(image.file, "cannot be written" + (error.empty() ? "" : " (" + error + ")"));
  }
}

}  // namespace

void write_rig_band_image(const RigBandImage& image, const torch::Tensor& counts) {
  write_band(image, counts, xmp_of(image));
}

void write_band_tiff(const fs::path& path, const torch::Tensor& counts, const std::string& xmp) {
  RigBandImage plain;
  plain.file = path;
  write_band(plain, counts, xmp);
}

core::Intrinsics rig_intrinsics(const RigBandImage& b) {
  if (!(b.focal_length_mm > 0))
    throw core::Error(b.file,
                      "its XMP has no PerspectiveFocalLength: the band camera's focal "
                      "length is unknown");
  const bool in_px = b.focal_length_units == "px";
  if (!in_px && !(b.px_per_mm > 0))
    throw core::Error(b.file, "its EXIF has no FocalPlaneXResolution: the focal length (" +
                                  std::to_string(b.focal_length_mm) +
                                  " mm) cannot be put in pixels");
  core::Intrinsics k;
  k.width = int(b.width);
  k.height = int(b.height);
  k.fx = k.fy = in_px ? b.focal_length_mm : b.focal_length_mm * b.px_per_mm;
  // The principal point is in mm whichever unit the focal length has.
  const bool has_pp = b.principal_point_mm.size() == 2 && b.px_per_mm > 0;
  k.cx = has_pp ? b.principal_point_mm[0] * b.px_per_mm : 0.5 * double(b.width);
  k.cy = has_pp ? b.principal_point_mm[1] * b.px_per_mm : 0.5 * double(b.height);
  if (b.distortion.size() == 5) {
    k.k1 = b.distortion[0];
    k.k2 = b.distortion[1];
    k.k3 = b.distortion[2];
    k.p1 = b.distortion[3];
    k.p2 = b.distortion[4];
  } else if (!b.distortion.empty()) {
    throw core::Error(b.file, "XMP PerspectiveDistortion has " +
                                  std::to_string(b.distortion.size()) +
                                  " values, expected 5 (k1, k2, k3, p1, p2)");
  }
  return k;
}

core::Mat3 rig_relative_rotation(const std::vector<double>& angles_deg) {
  if (angles_deg.size() != 3) return core::Mat3{};
  const double k = 3.14159265358979323846 / 180;
  const double a = angles_deg[0] * k, b = angles_deg[1] * k, c = angles_deg[2] * k;
  core::Mat3 rx = core::Mat3{}, ry = core::Mat3{}, rz = core::Mat3{};
  rx(1, 1) = std::cos(a), rx(1, 2) = -std::sin(a), rx(2, 1) = std::sin(a), rx(2, 2) = std::cos(a);
  ry(0, 0) = std::cos(b), ry(0, 2) = std::sin(b), ry(2, 0) = -std::sin(b), ry(2, 2) = std::cos(b);
  rz(0, 0) = std::cos(c), rz(0, 1) = -std::sin(c), rz(1, 0) = std::sin(c), rz(1, 1) = std::cos(c);
  return rz * ry * rx;
}

double rig_relative_angle_deg(const std::vector<double>& angles_deg) {
  if (angles_deg.size() != 3) return 0;
  const double k = 3.14159265358979323846 / 180;
  const double a = angles_deg[0] * k, b = angles_deg[1] * k, c = angles_deg[2] * k;
  // trace of Rz(c) Ry(b) Rx(a)
  const double trace = std::cos(b) * std::cos(c) +
                       (std::sin(a) * std::sin(b) * std::sin(c) + std::cos(a) * std::cos(c)) +
                       std::cos(a) * std::cos(b);
  return std::acos(std::clamp((trace - 1) / 2, -1.0, 1.0)) / k;
}

}  // namespace ddhgs::io
