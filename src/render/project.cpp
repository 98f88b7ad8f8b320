#include "render/project.h"

#include <ATen/Parallel.h>

#include <cmath>

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

// Everything the forward computes per Gaussian that the backward reuses.
struct GaussianGeometry {
  double mc[3];     // camera-space mean
  double view[9];   // world-to-camera rotation
  double rq[9];     // rotation of the Gaussian
  double scale[3];  // exp(log_scales)
  double sigma[9];  // 3D covariance
  double jac[6];    // 2x3 EWA Jacobian
  double tmat[6];   // J * view, 2x3
  double cov2[3];   // dilated 2D covariance (a, b, c)
  bool clamp_x, clamp_y;
  double rx, ry;  // clamped x/z, y/z
  Quat q;         // normalised quaternion
  double qnorm;
};

GaussianGeometry geometry(const float* m, const float* ls, const float* qr, const RenderCamera& cam,
                          const std::array<double, 4>& lim) {
  GaussianGeometry g;
  const float* v = cam.world_to_camera;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) g.view[r * 3 + c] = v[r * 4 + c];
    g.mc[r] = v[r * 4] * double(m[0]) + v[r * 4 + 1] * double(m[1]) + v[r * 4 + 2] * double(m[2]) +
              v[r * 4 + 3];
  }
  g.qnorm = std::sqrt(double(qr[0]) * qr[0] + double(qr[1]) * qr[1] + double(qr[2]) * qr[2] +
                      double(qr[3]) * qr[3]);
  g.q = {qr[0] / g.qnorm, qr[1] / g.qnorm, qr[2] / g.qnorm, qr[3] / g.qnorm};
  const M3 rq = rotation_from(g.q);
  std::copy(rq.begin(), rq.end(), g.rq);
  for (int i = 0; i < 3; ++i) g.scale[i] = std::exp(double(ls[i]));
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      double s = 0;
      for (int k = 0; k < 3; ++k) s += g.rq[i * 3 + k] * g.rq[j * 3 + k] * g.scale[k] * g.scale[k];
      g.sigma[i * 3 + j] = s;
    }
  const double z = g.mc[2];
  const double tx = g.mc[0] / z, ty = g.mc[1] / z;
  g.rx = std::fmin(std::fmax(tx, -lim[0]), lim[1]);
  g.ry = std::fmin(std::fmax(ty, -lim[2]), lim[3]);
  g.clamp_x = g.rx != tx;
  g.clamp_y = g.ry != ty;
  g.jac[0] = cam.fx / z, g.jac[1] = 0, g.jac[2] = -cam.fx * g.rx / z;
  g.jac[3] = 0, g.jac[4] = cam.fy / z, g.jac[5] = -cam.fy * g.ry / z;
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c) {
      double s = 0;
      for (int k = 0; k < 3; ++k) s += g.jac[r * 3 + k] * g.view[k * 3 + c];
      g.tmat[r * 3 + c] = s;
    }
  double ts[6];  // T * Sigma
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c) {
      double s = 0;
      for (int k = 0; k < 3; ++k) s += g.tmat[r * 3 + k] * g.sigma[k * 3 + c];
      ts[r * 3 + c] = s;
    }
  auto dot3 = [](const double* a, const double* b) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  };
  // 0.3 px^2 dilation: every splat covers at least about a pixel (anti-aliasing).
  g.cov2[0] = dot3(ts, g.tmat) + 0.3;
  g.cov2[1] = dot3(ts, g.tmat + 3);
  g.cov2[2] = dot3(ts + 3, g.tmat + 3) + 0.3;
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
  // principal point and stays sensible for an off-centre one.
  const double tan_x = 0.5 * cam.width / cam.fx, tan_y = 0.5 * cam.height / cam.fy;
  return {cam.cx / cam.fx + 0.3 * tan_x, (cam.width - cam.cx) / cam.fx + 0.3 * tan_x,
          cam.cy / cam.fy + 0.3 * tan_y, (cam.height - cam.cy) / cam.fy + 0.3 * tan_y};
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

  at::parallel_for(0, count, 2048, [&](int64_t begin, int64_t end) {
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

  at::parallel_for(0, count, 2048, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      const double o = op[i];
      glo[i] = float(dop[i] * o * (1 - o));
      const float* v = cam.world_to_camera;
      const float* mi = m + 3 * i;
      const double z = v[8] * double(mi[0]) + v[9] * double(mi[1]) + v[10] * double(mi[2]) + v[11];
      if (!(z > cam.near_plane)) continue;
      const GaussianGeometry g = geometry(mi, ls + 3 * i, qr + 4 * i, cam, lim);
      double dmc[3] = {0, 0, ddep[i]};
      // Screen position.
      const double du = dm2[2 * i], dv = dm2[2 * i + 1];
      dmc[0] += du * cam.fx / z;
      dmc[1] += dv * cam.fy / z;
      dmc[2] -= (du * cam.fx * g.mc[0] + dv * cam.fy * g.mc[1]) / (z * z);
      if (rad[i] > 0) {
        // conic = inverse(cov2): dCov = -K dK K, with dK in full symmetric form.
        const double k[4] = {con[3 * i], con[3 * i + 1], con[3 * i + 1], con[3 * i + 2]};
        const double dk[4] = {dcon[3 * i], 0.5 * dcon[3 * i + 1], 0.5 * dcon[3 * i + 1],
                              dcon[3 * i + 2]};
        double kd[4], gc[4];
        for (int r = 0; r < 2; ++r)
          for (int c = 0; c < 2; ++c) kd[r * 2 + c] = k[r * 2] * dk[c] + k[r * 2 + 1] * dk[2 + c];
        for (int r = 0; r < 2; ++r)
          for (int c = 0; c < 2; ++c)
            gc[r * 2 + c] = -(kd[r * 2] * k[c] + kd[r * 2 + 1] * k[2 + c]);
        // cov2 = T Sigma T^T: dT = 2 gc T Sigma, dSigma = T^T gc T.
        double gct[6], dtm[6], dsig[9];
        for (int r = 0; r < 2; ++r)
          for (int c = 0; c < 3; ++c)
            gct[r * 3 + c] = gc[r * 2] * g.tmat[c] + gc[r * 2 + 1] * g.tmat[3 + c];
        for (int r = 0; r < 2; ++r)
          for (int c = 0; c < 3; ++c) {
            double s = 0;
            for (int q = 0; q < 3; ++q) s += gct[r * 3 + q] * g.sigma[q * 3 + c];
            dtm[r * 3 + c] = 2 * s;
          }
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c)
            dsig[r * 3 + c] = g.tmat[r] * gct[c] + g.tmat[3 + r] * gct[3 + c];
        // T = J view: dJ = dT view^T.
        double dj[6];
        for (int r = 0; r < 2; ++r)
          for (int c = 0; c < 3; ++c) {
            double s = 0;
            for (int q = 0; q < 3; ++q) s += dtm[r * 3 + q] * g.view[c * 3 + q];
            dj[r * 3 + c] = s;
          }
        // J = [[fx/z, 0, -fx rx/z], [0, fy/z, -fy ry/z]], rx = clamp(x/z).
        dmc[2] -= (dj[0] * cam.fx + dj[4] * cam.fy) / (z * z);
        dmc[2] += (dj[2] * cam.fx * g.rx + dj[5] * cam.fy * g.ry) / (z * z);
        const double drx = -dj[2] * cam.fx / z, dry = -dj[5] * cam.fy / z;
        if (!g.clamp_x) dmc[0] += drx / z, dmc[2] -= drx * g.mc[0] / (z * z);
        if (!g.clamp_y) dmc[1] += dry / z, dmc[2] -= dry * g.mc[1] / (z * z);
        // Sigma = M M^T with M = Rq S: dM = 2 dSigma M.
        double dr[9];
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) {
            double dmrc = 0;
            for (int q = 0; q < 3; ++q) dmrc += dsig[r * 3 + q] * g.rq[q * 3 + c];
            dmrc *= 2 * g.scale[c];
            dr[r * 3 + c] = dmrc * g.scale[c];
            gls[3 * i + c] += float(dmrc * g.rq[r * 3 + c] * g.scale[c]);
          }
        const double w = g.q.w, x = g.q.x, y = g.q.y, zq = g.q.z;
        double dq[4] = {
            2 * (-zq * dr[1] + y * dr[2] + zq * dr[3] - x * dr[5] - y * dr[6] + x * dr[7]),
            2 * (y * dr[1] + zq * dr[2] + y * dr[3] - 2 * x * dr[4] - w * dr[5] + zq * dr[6] +
                 w * dr[7] - 2 * x * dr[8]),
            2 * (-2 * y * dr[0] + x * dr[1] + w * dr[2] + x * dr[3] + zq * dr[5] - w * dr[6] +
                 zq * dr[7] - 2 * y * dr[8]),
            2 * (-2 * zq * dr[0] - w * dr[1] + x * dr[2] + w * dr[3] - 2 * zq * dr[4] + y * dr[5] +
                 x * dr[6] + y * dr[7])};
        // Normalisation: project out the radial component.
        const double qd = w * dq[0] + x * dq[1] + y * dq[2] + zq * dq[3];
        const double qn[4] = {w, x, y, zq};
        for (int c = 0; c < 4; ++c) gq[4 * i + c] = float((dq[c] - qn[c] * qd) / g.qnorm);
      }
      for (int c = 0; c < 3; ++c)
        gm[3 * i + c] = float(g.view[c] * dmc[0] + g.view[3 + c] * dmc[1] + g.view[6 + c] * dmc[2]);
    }
  });
  return out;
}

}  // namespace ddhgs::render
