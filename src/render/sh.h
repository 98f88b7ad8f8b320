// Real spherical harmonics of degree 0-3 with the constants and sign
// conventions of 3D Gaussian Splatting, so coefficients exported by other
// 3DGS tools evaluate to the same colours here. The entry point eval_sh is
// declared in render/rasterize.h.
#pragma once

namespace ddhgs::render {

constexpr int kMaxShDegree = 3;

// Coefficients per band for a degree: 1, 4, 9, 16.
constexpr int sh_coeff_count(int degree) {
  return (degree + 1) * (degree + 1);
}

namespace sh_constants {
constexpr double C0 = 0.28209479177387814;
constexpr double C1 = 0.4886025119029199;
constexpr double C2[5] = {1.0925484305920792, -1.0925484305920792, 0.31539156525252005,
                          -1.0925484305920792, 0.5462742152960396};
constexpr double C3[7] = {-0.5900435899266435, 2.890611442640554,   -0.4570457994644658,
                          0.3731763325901154,  -0.4570457994644658, 1.445305721320277,
                          -0.5900435899266435};
}  // namespace sh_constants

// Basis values Y[k] for k < sh_coeff_count(Degree) at the unit direction
// (x, y, z), and optionally their partial derivatives dY[k][axis] taken with
// x, y, z as independent variables (the caller chains through normalisation).
template <int Degree, typename T>
inline void sh_basis(T x, T y, T z, T* Y, T (*dY)[3] = nullptr) {
  using namespace sh_constants;
  Y[0] = T(C0);
  if (dY) dY[0][0] = dY[0][1] = dY[0][2] = T(0);
  if constexpr (Degree >= 1) {
    Y[1] = T(-C1) * y;
    Y[2] = T(C1) * z;
    Y[3] = T(-C1) * x;
    if (dY) {
      dY[1][0] = 0, dY[1][1] = T(-C1), dY[1][2] = 0;
      dY[2][0] = 0, dY[2][1] = 0, dY[2][2] = T(C1);
      dY[3][0] = T(-C1), dY[3][1] = 0, dY[3][2] = 0;
    }
  }
  if constexpr (Degree >= 2) {
    const T xx = x * x, yy = y * y, zz = z * z;
    Y[4] = T(C2[0]) * x * y;
    Y[5] = T(C2[1]) * y * z;
    Y[6] = T(C2[2]) * (2 * zz - xx - yy);
    Y[7] = T(C2[3]) * x * z;
    Y[8] = T(C2[4]) * (xx - yy);
    if (dY) {
      dY[4][0] = T(C2[0]) * y, dY[4][1] = T(C2[0]) * x, dY[4][2] = 0;
      dY[5][0] = 0, dY[5][1] = T(C2[1]) * z, dY[5][2] = T(C2[1]) * y;
      dY[6][0] = T(C2[2]) * -2 * x, dY[6][1] = T(C2[2]) * -2 * y, dY[6][2] = T(C2[2]) * 4 * z;
      dY[7][0] = T(C2[3]) * z, dY[7][1] = 0, dY[7][2] = T(C2[3]) * x;
      dY[8][0] = T(C2[4]) * 2 * x, dY[8][1] = T(C2[4]) * -2 * y, dY[8][2] = 0;
    }
  }
  if constexpr (Degree >= 3) {
    const T xx = x * x, yy = y * y, zz = z * z;
    Y[9] = T(C3[0]) * y * (3 * xx - yy);
    Y[10] = T(C3[1]) * x * y * z;
    Y[11] = T(C3[2]) * y * (4 * zz - xx - yy);
    Y[12] = T(C3[3]) * z * (2 * zz - 3 * xx - 3 * yy);
    Y[13] = T(C3[4]) * x * (4 * zz - xx - yy);
    Y[14] = T(C3[5]) * z * (xx - yy);
    Y[15] = T(C3[6]) * x * (xx - 3 * yy);
    if (dY) {
      dY[9][0] = T(C3[0]) * 6 * x * y;
      dY[9][1] = T(C3[0]) * (3 * xx - 3 * yy);
      dY[9][2] = 0;
      dY[10][0] = T(C3[1]) * y * z;
      dY[10][1] = T(C3[1]) * x * z;
      dY[10][2] = T(C3[1]) * x * y;
      dY[11][0] = T(C3[2]) * -2 * x * y;
      dY[11][1] = T(C3[2]) * (4 * zz - xx - 3 * yy);
      dY[11][2] = T(C3[2]) * 8 * y * z;
      dY[12][0] = T(C3[3]) * -6 * x * z;
      dY[12][1] = T(C3[3]) * -6 * y * z;
      dY[12][2] = T(C3[3]) * (6 * zz - 3 * xx - 3 * yy);
      dY[13][0] = T(C3[4]) * (4 * zz - 3 * xx - yy);
      dY[13][1] = T(C3[4]) * -2 * x * y;
      dY[13][2] = T(C3[4]) * 8 * x * z;
      dY[14][0] = T(C3[5]) * 2 * x * z;
      dY[14][1] = T(C3[5]) * -2 * y * z;
      dY[14][2] = T(C3[5]) * (xx - yy);
      dY[15][0] = T(C3[6]) * (3 * xx - 3 * yy);
      dY[15][1] = T(C3[6]) * -6 * x * y;
      dY[15][2] = 0;
    }
  }
}

}  // namespace ddhgs::render
