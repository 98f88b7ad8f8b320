#include "render/project.h"

#include <cmath>

#include "core/mat.h"
#include "core/parallel.h"
#include "render/tiles.h"

namespace ddhgs::render {
namespace {

// The projection runs in double per Gaussian: it is cheap next to blending and
// keeps thin or near-plane Gaussians accurate.
using M3 = std::array<double, 9>;  // row-major 3x3

struct Quat {
  double w, x, y, z;
};

M3 rotation_from(const Quat& q) {
  const double w = q.w, x = q.x, y = q.y, z = q.z;
  return {1 - 2 * (y * y + z * z), 2 * (x * y - w * z),     2 * (x * z + w * y),
          2 * (x * y + w * z),     1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
          2 * (x * z - w * y),     2 * (y * z + w * x),     1 - 2 * (x * x + y * y)};
}

// 2x3 row-major: the EWA Jacobian J and T = J W.
struct Mat23 {
  std::array<double, 6> m{};
  double& operator()(int r, int c) { return m[r * 3 + c]; }
  double operator()(int r, int c) const { return m[r * 3 + c]; }
};

// 2x2 row-major, symmetric where it stands for a 2D covariance or conic.
using Mat2 = std::array<double, 4>;

core::Mat3 as_mat3(const M3& a) {
  core::Mat3 r;
  r.m = a;
  return r;
}

// a * b for a 2x3 and a 3x3 matrix.
Mat23 times(const Mat23& a, const core::Mat3& b) {
  Mat23 out;
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c)
      out(r, c) = a(r, 0) * b(0, c) + a(r, 1) * b(1, c) + a(r, 2) * b(2, c);
  return out;
}

// a * b for a 2x2 and a 2x3 matrix.
Mat23 times(const Mat2& a, const Mat23& b) {
  Mat23 out;
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c) out(r, c) = a[r * 2] * b(0, c) + a[r * 2 + 1] * b(1, c);
  return out;
}

// a^T * b for two 2x3 matrices: 3x3.
core::Mat3 transposed_times(const Mat23& a, const Mat23& b) {
  core::Mat3 out;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) out(r, c) = a(0, r) * b(0, c) + a(1, r) * b(1, c);
  return out;
}

// Everything the forward computes per Gaussian that the backward reuses.
struct GaussianGeometry {
  core::Vec3 mc;                // camera-space mean
  core::Mat3 view;              // world-to-camera rotation W
  core::Mat3 rq;                // rotation of the Gaussian
  std::array<double, 3> scale;  // exp(log_scales)
  core::Mat3 sigma;             // 3D covariance Rq S^2 Rq^T
  Mat23 tmat;                   // T = J W
  bool clamp_x, clamp_y;
  double rx, ry;  // clamped x/z, y/z
  Quat q;         // normalised quaternion
  double qnorm;
};

GaussianGeometry geometry(const float* m, const float* ls, const float* qr, const RenderCamera& cam,
                          const std::array<double, 4>& lim) {
  GaussianGeometry g;
  const float* v = cam.world_to_camera;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) g.view(r, c) = v[r * 4 + c];
  g.mc = g.view * core::Vec3{m[0], m[1], m[2]} + core::Vec3{v[3], v[7], v[11]};
  g.qnorm = std::sqrt(double(qr[0]) * qr[0] + double(qr[1]) * qr[1] + double(qr[2]) * qr[2] +
                      double(qr[3]) * qr[3]);
  g.q = {qr[0] / g.qnorm, qr[1] / g.qnorm, qr[2] / g.qnorm, qr[3] / g.qnorm};
  g.rq = as_mat3(rotation_from(g.q));
  for (int i = 0; i < 3; ++i) g.scale[size_t(i)] = std::exp(double(ls[i]));
  core::Mat3 scaled = g.rq;  // Rq S
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) scaled(r, c) *= g.scale[size_t(c)];
  g.sigma = scaled * scaled.transposed();
  const double z = g.mc.z;
  const double tx = g.mc.x / z, ty = g.mc.y / z;
  g.rx = std::fmin(std::fmax(tx, -lim[0]), lim[1]);
  g.ry = std::fmin(std::fmax(ty, -lim[2]), lim[3]);
  g.clamp_x = g.rx != tx;
  g.clamp_y = g.ry != ty;
  Mat23 jac;
  jac(0, 0) = cam.fx / z, jac(0, 2) = -cam.fx * g.rx / z;
  jac(1, 1) = cam.fy / z, jac(1, 2) = -cam.fy * g.ry / z;
  g.tmat = times(jac, g.view);
  return g;
}

// The forward's share of geometry(): camera-space mean mc and dilated 2D
// covariance cov2 (a, b, c) by the same formulas, without the intermediates
// only the backward needs: T Sigma T^T is formed as M M^T with
// M = T R diag(scale), about half the arithmetic and no divisions by z.
void mean_and_cov2(const float* m, const float* ls, const float* qr, const RenderCamera& cam,
                   const std::array<double, 4>& lim, double mc[3], double cov2[3]) {
  const float* v = cam.world_to_camera;
  for (int r = 0; r < 3; ++r)
    mc[r] = v[r * 4] * double(m[0]) + v[r * 4 + 1] * double(m[1]) + v[r * 4 + 2] * double(m[2]) +
            v[r * 4 + 3];
  const double inv_norm = 1.0 / std::sqrt(double(qr[0]) * qr[0] + double(qr[1]) * qr[1] +
                                          double(qr[2]) * qr[2] + double(qr[3]) * qr[3]);
  const M3 rq =
      rotation_from({qr[0] * inv_norm, qr[1] * inv_norm, qr[2] * inv_norm, qr[3] * inv_norm});
  const double inv_z = 1.0 / mc[2];
  const double tx = mc[0] * inv_z, ty = mc[1] * inv_z;
  const double rx = tx < -lim[0] ? -lim[0] : tx > lim[1] ? lim[1] : tx;
  const double ry = ty < -lim[2] ? -lim[2] : ty > lim[3] ? lim[3] : ty;
  // Rows of T = J W: (fx / z) (W0 - rx W2) and (fy / z) (W1 - ry W2).
  double t[2][3];
  for (int c = 0; c < 3; ++c) {
    t[0][c] = cam.fx * inv_z * (v[c] - rx * v[8 + c]);
    t[1][c] = cam.fy * inv_z * (v[4 + c] - ry * v[8 + c]);
  }
  double mm[2][3];
  for (int k = 0; k < 3; ++k) {
    const double s = std::exp(double(ls[k]));
    for (int r = 0; r < 2; ++r)
      mm[r][k] = s * (t[r][0] * rq[k] + t[r][1] * rq[3 + k] + t[r][2] * rq[6 + k]);
  }
  auto dot3 = [](const double* a, const double* b) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  };
  // 0.3 px^2 dilation, as in geometry().
  cov2[0] = dot3(mm[0], mm[0]) + 0.3;
  cov2[1] = dot3(mm[0], mm[1]);
  cov2[2] = dot3(mm[1], mm[1]) + 0.3;
}

}  // namespace

std::array<double, 4> jacobian_clamp_limits(const RenderCamera& cam) {
  // 3DGS clamps at 1.3 tan(fov/2); gsplat's form keeps that for a centred
  // principal point and stays sensible for an off-centre one. A part of a
  // view clamps where the whole view does.
  const bool part = cam.frame_width > 0;
  const double width = part ? cam.frame_width : cam.width;
  const double height = part ? cam.frame_height : cam.height;
  const double cx = double(cam.cx) + (part ? cam.frame_x : 0);
  const double cy = double(cam.cy) + (part ? cam.frame_y : 0);
  const double tan_x = 0.5 * width / cam.fx, tan_y = 0.5 * height / cam.fy;
  return {cx / cam.fx + 0.3 * tan_x, (width - cx) / cam.fx + 0.3 * tan_x, cy / cam.fy + 0.3 * tan_y,
          (height - cy) / cam.fy + 0.3 * tan_y};
}

Projected project_forward(const torch::Tensor& means, const torch::Tensor& log_scales,
                          const torch::Tensor& quats, const torch::Tensor& logit_opacities,
                          const RenderCamera& cam) {
  const int64_t count = means.size(0);
  const auto f32 = torch::dtype(torch::kFloat32);
  Projected out{torch::zeros({count, 2}, f32), torch::zeros({count, 3}, f32),
                torch::zeros({count}, f32), torch::zeros({count}, f32),
                torch::zeros({count}, torch::dtype(torch::kInt32))};
  const float* m = means.data_ptr<float>();
  const float* ls = log_scales.data_ptr<float>();
  const float* qr = quats.data_ptr<float>();
  const float* lo = logit_opacities.data_ptr<float>();
  float* m2 = out.means2d.data_ptr<float>();
  float* con = out.conics.data_ptr<float>();
  float* dep = out.depths.data_ptr<float>();
  float* op = out.opacities.data_ptr<float>();
  int32_t* rad = out.radii.data_ptr<int32_t>();
  const auto lim = jacobian_clamp_limits(cam);
  const int tiles_x = tiles_along(cam.width), tiles_y = tiles_along(cam.height);

  core::parallel_for(0, count, 2048, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      op[i] = float(1.0 / (1.0 + std::exp(-double(lo[i]))));
      const float* mi = m + 3 * i;
      const float* v = cam.world_to_camera;
      const double z = v[8] * double(mi[0]) + v[9] * double(mi[1]) + v[10] * double(mi[2]) + v[11];
      dep[i] = float(z);
      if (!(z > cam.near_plane)) continue;
      double mc[3], cov2[3];
      mean_and_cov2(mi, ls + 3 * i, qr + 4 * i, cam, lim, mc, cov2);
      const double u = cam.fx * mc[0] / z + cam.cx, w = cam.fy * mc[1] / z + cam.cy;
      m2[2 * i] = float(u), m2[2 * i + 1] = float(w);
      const double a = cov2[0], b = cov2[1], c = cov2[2];
      const double det = a * c - b * b;
      if (!(det > 0)) continue;
      con[3 * i] = float(c / det), con[3 * i + 1] = float(-b / det),
              con[3 * i + 2] = float(a / det);
      const double mid = 0.5 * (a + c);
      const double lambda = mid + std::sqrt(std::fmax(0.1, mid * mid - det));
      const double radius = std::fmin(std::ceil(3.0 * std::sqrt(lambda)), double(1 << 30));
      if (tile_rect(m2[2 * i], m2[2 * i + 1], radius, tiles_x, tiles_y).empty()) continue;
      rad[i] = int32_t(radius);
    }
  });
  return out;
}

namespace {

// The backward, one vector-Jacobian product per step of the forward, from
// the screen-space gradients back to the 3D parameters.

// conic = inverse(cov2): dcov2 = -K dK K, with dK in full symmetric form
// (the conic's off-diagonal B stands for two entries).
Mat2 conic_vjp(const float* conic, const float* d_conic) {
  const Mat2 k = {conic[0], conic[1], conic[1], conic[2]};
  const Mat2 dk = {d_conic[0], 0.5 * d_conic[1], 0.5 * d_conic[1], d_conic[2]};
  Mat2 kdk{}, out{};
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 2; ++c) kdk[r * 2 + c] = k[r * 2] * dk[c] + k[r * 2 + 1] * dk[2 + c];
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 2; ++c) out[r * 2 + c] = -(kdk[r * 2] * k[c] + kdk[r * 2 + 1] * k[2 + c]);
  return out;
}

// cov2 = T Sigma T^T (+ dilation): dT = 2 dcov2 T Sigma, dSigma = T^T dcov2 T.
struct Cov2Grads {
  Mat23 d_tmat;
  core::Mat3 d_sigma;
};
Cov2Grads cov2_vjp(const Mat2& d_cov2, const GaussianGeometry& g) {
  const Mat23 gt = times(d_cov2, g.tmat);  // dcov2 T
  Cov2Grads out;
  out.d_tmat = times(gt, g.sigma);
  for (double& x : out.d_tmat.m) x *= 2;
  out.d_sigma = transposed_times(g.tmat, gt);
  return out;
}

// T = J W: dJ = dT W^T; then J = [[fx/z, 0, -fx rx/z], [0, fy/z, -fy ry/z]]
// with rx = x/z and ry = y/z unless clamped: the camera-space mean's share.
core::Vec3 jacobian_vjp(const Mat23& d_tmat, const GaussianGeometry& g, const RenderCamera& cam) {
  const Mat23 dj = times(d_tmat, g.view.transposed());
  const double z = g.mc.z;
  core::Vec3 d_mc;
  d_mc.z -= (dj(0, 0) * cam.fx + dj(1, 1) * cam.fy) / (z * z);
  d_mc.z += (dj(0, 2) * cam.fx * g.rx + dj(1, 2) * cam.fy * g.ry) / (z * z);
  const double drx = -dj(0, 2) * cam.fx / z, dry = -dj(1, 2) * cam.fy / z;
  if (!g.clamp_x) d_mc.x += drx / z, d_mc.z -= drx * g.mc.x / (z * z);
  if (!g.clamp_y) d_mc.y += dry / z, d_mc.z -= dry * g.mc.y / (z * z);
  return d_mc;
}

// Sigma = M M^T with M = Rq S: dM = 2 dSigma M, dRq = dM S, and each log
// scale gets dM's column . Rq's column times its scale.
struct SigmaGrads {
  core::Mat3 d_rotation;
  std::array<double, 3> d_log_scales{};
};
SigmaGrads sigma_vjp(const core::Mat3& d_sigma, const GaussianGeometry& g) {
  const core::Mat3 ds_rq = d_sigma * g.rq;
  SigmaGrads out;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      const double s = g.scale[size_t(c)];
      const double dm = 2 * ds_rq(r, c) * s;
      out.d_rotation(r, c) = dm * s;
      out.d_log_scales[size_t(c)] += dm * g.rq(r, c) * s;
    }
  return out;
}

// Rq = R(q / |q|): the rotation's derivative by the normalised quaternion,
// then the normalisation (the radial component projected out).
std::array<double, 4> quat_vjp(const core::Mat3& d_rotation, const Quat& q, double qnorm) {
  const auto& dr = d_rotation.m;
  const double w = q.w, x = q.x, y = q.y, z = q.z;
  const std::array<double, 4> dq = {
      2 * (-z * dr[1] + y * dr[2] + z * dr[3] - x * dr[5] - y * dr[6] + x * dr[7]),
      2 * (y * dr[1] + z * dr[2] + y * dr[3] - 2 * x * dr[4] - w * dr[5] + z * dr[6] + w * dr[7] -
           2 * x * dr[8]),
      2 * (-2 * y * dr[0] + x * dr[1] + w * dr[2] + x * dr[3] + z * dr[5] - w * dr[6] + z * dr[7] -
           2 * y * dr[8]),
      2 * (-2 * z * dr[0] - w * dr[1] + x * dr[2] + w * dr[3] - 2 * z * dr[4] + y * dr[5] +
           x * dr[6] + y * dr[7])};
  const double radial = w * dq[0] + x * dq[1] + y * dq[2] + z * dq[3];
  const std::array<double, 4> qn = {w, x, y, z};
  std::array<double, 4> out{};
  for (size_t c = 0; c < 4; ++c) out[c] = (dq[c] - qn[c] * radial) / qnorm;
  return out;
}

// means2d = (fx x / z + cx, fy y / z + cy) and depth = z: the camera-space
// mean's share.
core::Vec3 screen_vjp(double du, double dv, double d_depth, const core::Vec3& mc,
                      const RenderCamera& cam) {
  const double z = mc.z;
  return {du * cam.fx / z, dv * cam.fy / z,
          d_depth - (du * cam.fx * mc.x + dv * cam.fy * mc.y) / (z * z)};
}

}  // namespace

ProjectGrads project_backward(const torch::Tensor& means, const torch::Tensor& log_scales,
                              const torch::Tensor& quats, const torch::Tensor& logit_opacities,
                              const RenderCamera& cam, const Projected& projected,
                              const torch::Tensor& d_means2d, const torch::Tensor& d_conics,
                              const torch::Tensor& d_depths, const torch::Tensor& d_opacities) {
  const int64_t count = means.size(0);
  ProjectGrads out{torch::zeros_like(means), torch::zeros_like(log_scales),
                   torch::zeros_like(quats), torch::zeros_like(logit_opacities)};
  const float* m = means.data_ptr<float>();
  const float* ls = log_scales.data_ptr<float>();
  const float* qr = quats.data_ptr<float>();
  const float* op = projected.opacities.data_ptr<float>();
  const float* con = projected.conics.data_ptr<float>();
  const int32_t* rad = projected.radii.data_ptr<int32_t>();
  const float* dm2 = d_means2d.data_ptr<float>();
  const float* dcon = d_conics.data_ptr<float>();
  const float* ddep = d_depths.data_ptr<float>();
  const float* dop = d_opacities.data_ptr<float>();
  float* gm = out.means.data_ptr<float>();
  float* gls = out.log_scales.data_ptr<float>();
  float* gq = out.quats.data_ptr<float>();
  float* glo = out.logit_opacities.data_ptr<float>();
  const auto lim = jacobian_clamp_limits(cam);

  core::parallel_for(0, count, 2048, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      const double o = op[i];
      glo[i] = float(dop[i] * o * (1 - o));  // sigmoid
      const float* v = cam.world_to_camera;
      const float* mi = m + 3 * i;
      const double z = v[8] * double(mi[0]) + v[9] * double(mi[1]) + v[10] * double(mi[2]) + v[11];
      if (!(z > cam.near_plane)) continue;
      const GaussianGeometry g = geometry(mi, ls + 3 * i, qr + 4 * i, cam, lim);
      core::Vec3 d_mc = screen_vjp(dm2[2 * i], dm2[2 * i + 1], ddep[i], g.mc, cam);
      if (rad[i] > 0) {
        const Cov2Grads d_cov2 = cov2_vjp(conic_vjp(con + 3 * i, dcon + 3 * i), g);
        d_mc = d_mc + jacobian_vjp(d_cov2.d_tmat, g, cam);
        const SigmaGrads d_sigma = sigma_vjp(d_cov2.d_sigma, g);
        for (size_t c = 0; c < 3; ++c) gls[3 * i + int64_t(c)] = float(d_sigma.d_log_scales[c]);
        const std::array<double, 4> dq = quat_vjp(d_sigma.d_rotation, g.q, g.qnorm);
        for (size_t c = 0; c < 4; ++c) gq[4 * i + int64_t(c)] = float(dq[c]);
      }
      // mc = W m + t: dm = W^T dmc.
      const core::Vec3 d_mean = g.view.transposed() * d_mc;
      gm[3 * i] = float(d_mean.x), gm[3 * i + 1] = float(d_mean.y), gm[3 * i + 2] = float(d_mean.z);
    }
  });
  return out;
}

}  // namespace ddhgs::render
