// Finding a survey target in a raster, as a surveyor checks a map: the
// centre of a black and white 2 x 2 checker (the north-east and south-west
// quarters dark, as `synth --gcp-targets` prints them) near where it should
// be, to a twentieth of a pixel.
#pragma once
#include <cstdint>
#include <functional>

namespace ddhgs::test {

struct TargetFix {
  double col = 0, row = 0;  // pixel coordinates of the centre (pixel centres at + 0.5)
  double contrast = 0;      // mean of the white quarters less the dark, at the centre found
  bool found = false;       // every pixel of the window held a value
};

// value(row, col): the raster (north up, rows going south), NaN where it
// holds nothing. The centre is sought within +-search pixels of (col0,
// row0) for a target `half` pixels from its centre to each edge: the
// candidate whose box-filtered checker template correlates best with the
// pixels inside the target.
TargetFix find_checker_target(const std::function<double(int64_t row, int64_t col)>& value,
                              int64_t width, int64_t height, double col0, double row0, double half,
                              double search);

}  // namespace ddhgs::test
