// fit_similarity: recovers a known scale, rotation and translation from
// matched points (exact and noisy, coplanar like a turntable's cameras),
// never returns a reflection, and refuses points on one line.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "core/error.h"
#include "core/similarity.h"

namespace ddhgs::core {
namespace {

Similarity known() {
  Similarity s;
  s.scale = 0.25;
  s.rotation = quat_to_rotation(0.8, -0.3, 0.4, 0.2);
  s.translation = {14.0, -0.5, 1.4};
  return s;
}

// Camera centres on a circle (a turntable ring), the plane z = 2.
std::vector<Vec3> ring(int n) {
  std::vector<Vec3> out;
  for (int i = 0; i < n; ++i) {
    double a = 2 * 3.14159265358979 * i / n;
    out.push_back({3 * std::cos(a), 3 * std::sin(a), 2});
  }
  return out;
}

std::vector<Vec3> mapped(const Similarity& s, const std::vector<Vec3>& from) {
  std::vector<Vec3> out;
  for (const Vec3& p : from) out.push_back(s.apply(p));
  return out;
}

void expect_same(const Similarity& a, const Similarity& b, double tol) {
  EXPECT_NEAR(a.scale, b.scale, tol);
  for (int i = 0; i < 9; ++i) EXPECT_NEAR(a.rotation.m[size_t(i)], b.rotation.m[size_t(i)], tol);
  EXPECT_NEAR(a.translation.x, b.translation.x, tol);
  EXPECT_NEAR(a.translation.y, b.translation.y, tol);
  EXPECT_NEAR(a.translation.z, b.translation.z, tol);
}

TEST(Similarity, RecoversAKnownMapFromCoplanarPoints) {
  const std::vector<Vec3> from = ring(12);
  Similarity fit = fit_similarity(from, mapped(known(), from));
  expect_same(fit, known(), 1e-10);
  EXPECT_NEAR(fit.rotation.determinant(), 1, 1e-12);
  EXPECT_NEAR(rms_residual(fit, from, mapped(known(), from)), 0, 1e-12);
}

TEST(Similarity, NoisyPointsGiveASmallResidual) {
  std::vector<Vec3> from = ring(40);
  from.push_back({0, 0, 5});
  std::vector<Vec3> to = mapped(known(), from);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0, 0.001);
  for (Vec3& p : to) p = p + Vec3{noise(rng), noise(rng), noise(rng)};
  Similarity fit = fit_similarity(from, to);
  expect_same(fit, known(), 0.01);
  // The residual is about the noise (sqrt(3) x 0.001 per point), far below the spread.
  EXPECT_LT(rms_residual(fit, from, to), 0.003);
  EXPECT_NEAR(rms_spread(to), 0.25 * rms_spread(from), 0.01);
}

TEST(Similarity, MirroredPointsGetAProperRotation) {
  std::vector<Vec3> from = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  std::vector<Vec3> to;
  for (const Vec3& p : from) to.push_back({p.x, p.y, -p.z});  // a reflection
  Similarity fit = fit_similarity(from, to);
  EXPECT_NEAR(fit.rotation.determinant(), 1, 1e-12);
  EXPECT_GT(rms_residual(fit, from, to), 0.1);
}

TEST(Similarity, RefusesTooFewOrCollinearPoints) {
  EXPECT_THROW(fit_similarity({{0, 0, 0}, {1, 0, 0}}, {{0, 0, 0}, {1, 0, 0}}), Error);
  std::vector<Vec3> line = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {3, 3, 3}};
  EXPECT_THROW(fit_similarity(line, line), Error);
}

}  // namespace
}  // namespace ddhgs::core
