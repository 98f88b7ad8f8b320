// One reader input encoded as a byte string, for the fuzzer (libFuzzer,
// tests/fuzz/fuzz_readers.cpp), its seed corpus (fuzz_seeds.cpp) and test_io's
// replay of the inputs the fuzzer once found (tests/fuzz/regressions/).
//
// Byte 0 picks the reader (ReaderKind, modulo their count); the rest is the
// file. ENVI takes two files: a 2-byte little-endian header length, the
// header, then the data file. Readers get real files in a scratch folder,
// as users give them.
#pragma once
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>

namespace ddhgs::fuzz {

enum class ReaderKind : uint8_t {
  Npy,
  TorchPt,
  Envi,
  Tiff,
  Png,
  Jpeg,
  GaussianPly,
  PointPly,
  ColmapCamerasBin,
  ColmapImagesBin,
  ColmapPointsBin,
  ColmapCamerasTxt,
  ColmapImagesTxt,
  ColmapPointsTxt,
  Transforms,
  CameraJson,
  Count
};

// The input that hands `file` (for ENVI: header and data) to reader `kind`.
std::string encode(ReaderKind kind, const std::string& file, const std::string& envi_data = {});

// Runs the reader on the decoded input inside scratch (a folder that exists).
// Returns normally when the reader succeeds or throws core::Error, the one
// way a reader may refuse input; anything else (another exception type, a
// crash, a sanitizer report) is a defect and aborts.
void run_input(const uint8_t* data, size_t size, const std::filesystem::path& scratch);

}  // namespace ddhgs::fuzz
