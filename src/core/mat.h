// Small fixed-size double-precision linear algebra for cameras and poses.
#pragma once
#include <array>
#include <cmath>

namespace ddhgs::core {

struct Vec3 {
  double x = 0, y = 0, z = 0;
  Vec3 operator+(const Vec3& o) const { return {x + o.x, y + o.y, z + o.z}; }
  Vec3 operator-(const Vec3& o) const { return {x - o.x, y - o.y, z - o.z}; }
  Vec3 operator*(double s) const { return {x * s, y * s, z * s}; }
  double dot(const Vec3& o) const { return x * o.x + y * o.y + z * o.z; }
  Vec3 cross(const Vec3& o) const {
    return {y * o.z - z * o.y, z * o.x - x * o.z, x * o.y - y * o.x};
  }
  double norm() const { return std::sqrt(dot(*this)); }
  Vec3 normalized() const {
    double n = norm();
    return n > 0 ? *this * (1.0 / n) : *this;
  }
};

// Row-major 3x3.
struct Mat3 {
  std::array<double, 9> m{1, 0, 0, 0, 1, 0, 0, 0, 1};
  double& operator()(int r, int c) { return m[r * 3 + c]; }
  double operator()(int r, int c) const { return m[r * 3 + c]; }
  Vec3 operator*(const Vec3& v) const {
    return {m[0] * v.x + m[1] * v.y + m[2] * v.z, m[3] * v.x + m[4] * v.y + m[5] * v.z,
            m[6] * v.x + m[7] * v.y + m[8] * v.z};
  }
  Mat3 operator*(const Mat3& o) const {
    Mat3 r;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        double s = 0;
        for (int k = 0; k < 3; ++k) s += (*this)(i, k) * o(k, j);
        r(i, j) = s;
      }
    return r;
  }
  Mat3 transposed() const {
    Mat3 r;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) r(i, j) = (*this)(j, i);
    return r;
  }
  double determinant() const {
    return m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6]) +
           m[2] * (m[3] * m[7] - m[4] * m[6]);
  }
};

// Row-major 4x4 rigid or projective transform.
struct Mat4 {
  std::array<double, 16> m{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  double& operator()(int r, int c) { return m[r * 4 + c]; }
  double operator()(int r, int c) const { return m[r * 4 + c]; }
  Mat4 operator*(const Mat4& o) const {
    Mat4 r;
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) {
        double s = 0;
        for (int k = 0; k < 4; ++k) s += (*this)(i, k) * o(k, j);
        r(i, j) = s;
      }
    return r;
  }
  Mat3 rotation() const {
    Mat3 r;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) r(i, j) = (*this)(i, j);
    return r;
  }
  Vec3 translation() const { return {m[3], m[7], m[11]}; }
  Vec3 transform_point(const Vec3& p) const { return rotation() * p + translation(); }
  static Mat4 from(const Mat3& r, const Vec3& t) {
    Mat4 out;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) out(i, j) = r(i, j);
    out(0, 3) = t.x;
    out(1, 3) = t.y;
    out(2, 3) = t.z;
    return out;
  }
  // Inverse of a rigid transform [R t; 0 1].
  Mat4 rigid_inverse() const {
    Mat3 rt = rotation().transposed();
    return from(rt, (rt * translation()) * -1.0);
  }
};

// Nearest rotation (polar decomposition via Newton iteration); removes the
// uniform scale that real transforms.json files carry in their rotation blocks.
Mat3 orthonormalize(const Mat3& r);

// Unit quaternion (w, x, y, z) <-> rotation matrix.
Mat3 quat_to_rotation(double w, double x, double y, double z);
std::array<double, 4> rotation_to_quat(const Mat3& r);

}  // namespace ddhgs::core
