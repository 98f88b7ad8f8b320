#include "process/cube_set.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>

#include "core/error.h"
#include "core/text.h"
#include "io/cube/cube.h"
#include "io/scene/scene.h"

namespace ddhgs::process {
namespace fs = std::filesystem;

namespace {

using core::lower;

bool is_cube_file(const fs::path& path) {
  static const char* exts[] = {".npy", ".pt", ".hdr", ".tif", ".tiff"};
  std::string ext = lower(path.extension().string());
  return std::any_of(std::begin(exts), std::end(exts), [&](const char* e) { return ext == e; });
}

std::vector<double> even_grid(const WavelengthRange& range, int64_t bands) {
  std::vector<double> out;
  for (int64_t b = 0; b < bands; ++b)
    out.push_back(bands > 1 ? range.first_nm +
                                  (range.last_nm - range.first_nm) * double(b) / double(bands - 1)
                            : range.first_nm);
  return out;
}

bool same_grid(const std::vector<double>& a, const std::vector<double>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (std::abs(a[i] - b[i]) > 1e-6) return false;
  return true;
}

// The ENVI headers of a Specim IQ capture's capture/ folder: the raw cube
// and the one header whose name starts with each reference's prefix.
struct SpecimCapture {
  fs::path cube, white, dark;
};
SpecimCapture specim_capture(const fs::path& folder) {
  SpecimCapture c;
  std::vector<fs::path> headers;
  for (const auto& entry : fs::directory_iterator(folder))
    if (entry.is_regular_file() && lower(entry.path().extension().string()) == ".hdr")
      headers.push_back(entry.path());
  std::sort(headers.begin(), headers.end());
  auto take = [&](fs::path* slot, const std::string& what, const fs::path& header) {
    core::require(slot->empty(), folder,
                  "holds two " + what + " (" + slot->filename().string() + ", " +
                      header.filename().string() + "); a Specim IQ capture has one");
    *slot = header;
  };
  for (const fs::path& header : headers) {
    const std::string name = header.filename().string();
    if (name.rfind("WHITEREF_", 0) == 0)
      take(&c.white, "white references", header);
    else if (name.rfind("DARKREF_", 0) == 0)
      take(&c.dark, "dark references", header);
    else
      take(&c.cube, "raw cubes", header);
  }
  core::require(!c.cube.empty() && !c.white.empty() && !c.dark.empty(), folder,
                "a Specim IQ capture folder needs the raw cube's .hdr, WHITEREF_*.hdr and "
                "DARKREF_*.hdr");
  return c;
}

// Specim IQ captures in dir (dir itself, or its sub-folders in name order,
// that hold capture/); none when there are none.
std::vector<SpecimCapture> specim_captures(const fs::path& dir) {
  if (fs::is_directory(dir / "capture")) return {specim_capture(dir / "capture")};
  std::vector<fs::path> folders;
  for (const auto& entry : fs::directory_iterator(dir))
    if (entry.is_directory() && fs::is_directory(entry.path() / "capture"))
      folders.push_back(entry.path() / "capture");
  std::sort(folders.begin(), folders.end());
  std::vector<SpecimCapture> out;
  for (const fs::path& folder : folders) out.push_back(specim_capture(folder));
  return out;
}

}  // namespace

WavelengthRange parse_wavelength_range(const std::string& text) {
  auto colon = text.find(':');
  WavelengthRange range;
  try {
    size_t used_first = 0, used_last = 0;
    if (colon == std::string::npos) throw std::invalid_argument("no colon");
    range.first_nm = std::stod(text.substr(0, colon), &used_first);
    range.last_nm = std::stod(text.substr(colon + 1), &used_last);
    if (used_first != colon || used_last != text.size() - colon - 1)
      throw std::invalid_argument("trailing text");
  } catch (const std::exception&) {
    throw core::Error("--wl-range '" + text + "': expected MIN:MAX in nm, e.g. 400:1000");
  }
  core::require(range.first_nm > 0 && range.last_nm > range.first_nm,
                "--wl-range '" + text + "': expected 0 < MIN < MAX (nm)");
  return range;
}

CubeSet scan_cubes(const fs::path& dir, const std::optional<WavelengthRange>& range) {
  core::require(fs::is_directory(dir), dir, "is not a folder of cubes");
  CubeSet set;
  set.dir = dir;
  for (const auto& entry : fs::directory_iterator(dir))
    if (entry.is_regular_file() && is_cube_file(entry.path())) set.files.push_back(entry.path());
  std::sort(set.files.begin(), set.files.end());
  if (set.files.empty())
    for (const SpecimCapture& c : specim_captures(dir)) {
      set.files.push_back(c.cube);
      set.white_refs.push_back(c.white);
      set.dark_refs.push_back(c.dark);
    }
  core::require(!set.files.empty(), dir,
                "holds no cube files (expected .npy, .pt, ENVI .hdr, .tif or .tiff, or Specim "
                "IQ capture folders)");

  std::map<std::string, fs::path> by_stem;
  std::vector<double> named_nm;
  fs::path named_by;
  for (const auto& file : set.files) {
    std::string stem = file.stem().string();
    auto [it, fresh] = by_stem.emplace(stem, file);
    core::require(fresh, file,
                  "has the same name as " + it->second.filename().string() +
                      "; every view needs a cube of its own name");
    set.names.push_back(stem);
    io::CubeInfo info = io::probe_cube(file);
    if (set.bands == 0) {
      set.height = info.height;
      set.width = info.width;
      set.bands = info.bands;
    }
    io::require_bands(file, info.bands, set.bands);
    core::require(info.height == set.height && info.width == set.width, file,
                  "is " + std::to_string(info.width) + "x" + std::to_string(info.height) +
                      " pixels, expected " + std::to_string(set.width) + "x" +
                      std::to_string(set.height) + " like " + set.files[0].filename().string());
    if (info.wavelengths_nm.empty()) continue;
    if (named_nm.empty()) {
      named_nm = info.wavelengths_nm;
      named_by = file;
    }
    core::require(same_grid(info.wavelengths_nm, named_nm), file,
                  "names other wavelengths than " + named_by.filename().string());
  }
  if (!named_nm.empty()) {
    set.wavelengths_nm = named_nm;
  } else {
    core::require(range.has_value(), set.files[0],
                  "names no wavelengths; pass --wl-range MIN:MAX (first and last band centre, "
                  "nm)");
    set.wavelengths_nm = even_grid(*range, set.bands);
  }
  return set;
}

}  // namespace ddhgs::process
