// `ddhgs process`, input: the cubes of one capture (a folder of .npy, .pt,
// ENVI or TIFF cubes of one size and band count) and their wavelengths.
#pragma once
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace ddhgs::process {

// The cubes of one capture, all of one size and band count.
struct CubeSet {
  std::filesystem::path dir;
  std::vector<std::filesystem::path> files;  // sorted by file name
  std::vector<std::string> names;            // file stems, unique
  int64_t height = 0, width = 0, bands = 0;  // pixels, pixels, bands
  std::vector<double> wavelengths_nm;        // one per band
  // A Specim IQ layout: each cube's white and dark reference (its capture
  // folder's WHITEREF_* and DARKREF_*); empty for a folder of cubes.
  std::vector<std::filesystem::path> white_refs, dark_refs;
};

// First and last band centres (nm) of an evenly spaced grid.
struct WavelengthRange {
  double first_nm = 0, last_nm = 0;
};
// "MIN:MAX" in nm; core::Error naming the option otherwise.
WavelengthRange parse_wavelength_range(const std::string& text);

// Cube files of dir (.npy .pt .hdr .tif .tiff; an ENVI pair counts once, by
// its .hdr), headers only. A folder with no cube files may hold Specim IQ
// captures instead (it or its sub-folders each hold capture/ with the raw
// ENVI cube, WHITEREF_*.hdr and DARKREF_*.hdr): their raw cubes, in folder
// order, with their references. range: the grid for cubes whose files name no
// wavelengths (.npy, .pt); files that name them must agree. core::Error
// naming the file or folder: no cubes, two cubes with one stem, unreadable
// header, band count or size differing from the first cube, no wavelengths.
CubeSet scan_cubes(const std::filesystem::path& dir,
                   const std::optional<WavelengthRange>& range = std::nullopt);

}  // namespace ddhgs::process
