#include "io/rig/rig_capture.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <set>

#include "core/error.h"
#include "core/text.h"
#include "io/cube/tiff_open.h"

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

}  // namespace

std::optional<std::string> xmp_property(const std::string& xmp, const std::string& name) {
  if (auto value = attribute(xmp, name)) return value;
  auto inner = element_inner(xmp, name);
  if (!inner || inner->find('<') != std::string::npos) return std::nullopt;  // a list
  return unescape(trim(*inner));
}

std::vector<std::string> xmp_list(const std::string& xmp, const std::string& name) {
  std::vector<std::string> items;
  auto inner = element_inner(xmp, name);
  if (inner && inner->find("<rdf:li") != std::string::npos) {
    for (size_t at = inner->find("<rdf:li"); at != std::string::npos;
         at = inner->find("<rdf:li", at + 1)) {
      const size_t open_end = inner->find('>', at);
      const size_t close = inner->find("</rdf:li>", open_end);
      if (open_end == std::string::npos || close == std::string::npos) break;
      items.push_back(unescape(trim(inner->substr(open_end + 1, close - open_end - 1))));
    }
    return items;
  }
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
  TIFFClose(tif);
  image.width = width;
  image.height = height;
  image.bits = bits;
  if (samples != 1)
    throw core::Error(file, "has " + std::to_string(samples) +
                                " samples per pixel; a rig band image holds one band");
  if (xmp.empty())
    throw core::Error(file, "has no XMP metadata: not a band image of a multispectral rig");
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
  image.principal_point_mm = numbers(xmp_list(xmp, "PrincipalPoint"), file, "PrincipalPoint");
  image.distortion = numbers(xmp_list(xmp, "PerspectiveDistortion"), file, "PerspectiveDistortion");
  image.rig_relatives_deg = numbers(xmp_list(xmp, "RigRelatives"), file, "RigRelatives");
  if (!image.rig_relatives_deg.empty() && image.rig_relatives_deg.size() != 3)
    throw core::Error(file, "XMP RigRelatives has " +
                                std::to_string(image.rig_relatives_deg.size()) +
                                " values, expected 3 angles");
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
