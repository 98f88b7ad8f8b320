// The .splat format of antimatter15's WebGL viewer, which the common web
// viewers load (PlayCanvas SuperSplat and engine, Spark, GaussianSplats3D):
// 32 bytes per Gaussian, no header, no view dependence, little endian:
//   float32 x, y, z          centre (scene units)
//   float32 sx, sy, sz       standard deviations (exp of the PLY's log scales)
//   uint8 r, g, b, a         DC colour (0.5 + C0 f_dc) and opacity, 0-1 as 0-255
//   uint8 qw, qx, qy, qz     unit rotation, each component q as round(128 q + 128)
// Gaussians are stored largest (size x opacity) first, the order that viewer
// streams them in.
#pragma once
#include <filesystem>

#include "io/ply/ply.h"

namespace ddhgs::io {

constexpr int64_t kSplatRecordBytes = 32;

// ply must have three channels (f_dc_0..2); higher SH coefficients are dropped.
// Atomic write; core::Error naming path otherwise.
void write_splat(const std::filesystem::path& path, const GaussianPly& ply);

}  // namespace ddhgs::io
