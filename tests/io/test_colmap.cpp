// COLMAP models: round trips in both formats, files written independently
// (Python struct, hand-written text), truncated and malformed files.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>

#include "core/error.h"
#include "io/colmap/colmap.h"
#include "io/files/atomic_file.h"
#include "support/error_text.h"
#include "support/test_support.h"

namespace ddhgs::io {
namespace {
namespace fs = std::filesystem;

ColmapModel sample_model() {
  ColmapModel m;
  m.cameras[1] = {1, "PINHOLE", 64, 48, {50.5, 51.25, 32.1, 23.9}};
  m.cameras[3] = {3, "OPENCV", 640, 512, {700, 701, 320, 256, -0.1, 0.01, 0.001, -0.002}};
  m.cameras[4] = {4, "SIMPLE_PINHOLE", 10, 8, {12.5, 5, 4}};
  for (int i = 0; i < 3; ++i) {
    ColmapImage image;
    image.image_id = 10 + i;
    double angle = 0.3 + i;
    image.qvec = {std::cos(angle / 2), 0.2 * std::sin(angle / 2), 0.0, 0.98 * std::sin(angle / 2)};
    image.tvec = {0.1 * i, -1.5, 3.0 + 1.0 / 3.0};
    image.camera_id = i == 2 ? 3 : 1;
    image.name = "frame " + std::to_string(i) + ".png";  // a space, as COLMAP allows
    for (int k = 0; k < i + 1; ++k) {
      image.xys.push_back({k + 0.5, 2.0 / 3.0 * k});
      image.point3d_ids.push_back(k == 0 ? -1 : 100 + k);
    }
    m.images.push_back(image);
  }
  for (int p = 0; p < 4; ++p) {
    ColmapPoint point;
    point.point3d_id = 100 + p;
    point.xyz = {p * 0.1, -p / 7.0, 1e-3 * p};
    point.rgb = {uint8_t(10 * p), 255, uint8_t(p)};
    point.error = 0.25 * p;
    for (int t = 0; t < p; ++t) point.track.emplace_back(10 + t, t);
    m.points.push_back(point);
  }
  return m;
}

void expect_same(const ColmapModel& a, const ColmapModel& b) {
  ASSERT_EQ(a.cameras.size(), b.cameras.size());
  for (const auto& [id, ca] : a.cameras) {
    ASSERT_TRUE(b.cameras.count(id)) << "camera " << id;
    const auto& cb = b.cameras.at(id);
    EXPECT_EQ(ca.model, cb.model);
    EXPECT_EQ(ca.width, cb.width);
    EXPECT_EQ(ca.height, cb.height);
    EXPECT_EQ(ca.params, cb.params);
  }
  ASSERT_EQ(a.images.size(), b.images.size());
  for (size_t i = 0; i < a.images.size(); ++i) {
    const auto& ia = a.images[i];
    const auto& ib = b.images[i];
    EXPECT_EQ(ia.image_id, ib.image_id);
    EXPECT_EQ(ia.qvec, ib.qvec);
    EXPECT_EQ(ia.tvec.x, ib.tvec.x);
    EXPECT_EQ(ia.tvec.y, ib.tvec.y);
    EXPECT_EQ(ia.tvec.z, ib.tvec.z);
    EXPECT_EQ(ia.camera_id, ib.camera_id);
    EXPECT_EQ(ia.name, ib.name);
    EXPECT_EQ(ia.xys, ib.xys);
    EXPECT_EQ(ia.point3d_ids, ib.point3d_ids);
  }
  ASSERT_EQ(a.points.size(), b.points.size());
  for (size_t i = 0; i < a.points.size(); ++i) {
    const auto& pa = a.points[i];
    const auto& pb = b.points[i];
    EXPECT_EQ(pa.point3d_id, pb.point3d_id);
    EXPECT_EQ(pa.xyz.x, pb.xyz.x);
    EXPECT_EQ(pa.xyz.y, pb.xyz.y);
    EXPECT_EQ(pa.xyz.z, pb.xyz.z);
    EXPECT_EQ(pa.rgb, pb.rgb);
    EXPECT_EQ(pa.error, pb.error);
    EXPECT_EQ(pa.track, pb.track);
  }
}

using test::contains;
using test::error_of;

TEST(Colmap, BinaryRoundTrip) {
  fs::path dir = test::temp_dir("colmap_bin");
  ColmapModel m = sample_model();
  write_colmap_binary(dir, m);
  expect_same(m, read_colmap_binary(dir));
  expect_same(m, read_colmap(dir));
}

TEST(Colmap, TextRoundTrip) {
  fs::path dir = test::temp_dir("colmap_txt");
  ColmapModel m = sample_model();
  write_colmap_text(dir, m);
  expect_same(m, read_colmap_text(dir));
  expect_same(m, read_colmap(dir));
}

TEST(Colmap, BinaryPreferredOverText) {
  fs::path dir = test::temp_dir("colmap_both");
  ColmapModel m = sample_model();
  write_colmap_text(dir, m);
  m.images.pop_back();
  write_colmap_binary(dir, m);
  EXPECT_EQ(read_colmap(dir).images.size(), m.images.size());
}

// Written byte by byte by Python's struct module, the way COLMAP's own
// scripts/python/read_write_model.py lays the files out.
TEST(Colmap, ReadsBinaryWrittenByPython) {
  fs::path dir = test::temp_dir("colmap_python");
  std::string script =
      "import struct, sys\n"
      "d = sys.argv[1]\n"
      "open(d + '/cameras.bin', 'wb').write(struct.pack('<Q', 1) + "
      "struct.pack('<iiQQ4d', 7, 1, 30, 20, 25.0, 26.0, 15.5, 10.5))\n"
      "img = struct.pack('<Q', 1) + struct.pack('<i7di', 5, 0.5, 0.5, 0.5, 0.5, 1.0, 2.0, 3.0, 7)"
      " + b'view_a.png\\x00' + struct.pack('<Q', 2) + struct.pack('<ddq', 1.5, 2.5, 9)"
      " + struct.pack('<ddq', 3.5, 4.5, -1)\n"
      "open(d + '/images.bin', 'wb').write(img)\n"
      "pts = struct.pack('<Q', 1) + struct.pack('<Q3d3Bd', 9, 0.25, -0.5, 4.0, 200, 100, 50, 0.75)"
      " + struct.pack('<Q', 1) + struct.pack('<ii', 5, 0)\n"
      "open(d + '/points3D.bin', 'wb').write(pts)\n";
  fs::path py = dir / "write.py";
  std::ofstream(py) << script;
  if (test::run_command(test::python() + " " + py.string() + " " + dir.string()) != 0)
    GTEST_SKIP() << "python3 unavailable";

  ColmapModel m = read_colmap(dir);
  ASSERT_EQ(m.cameras.size(), 1u);
  const ColmapCamera& cam = m.cameras.at(7);
  EXPECT_EQ(cam.model, "PINHOLE");
  EXPECT_EQ(cam.width, 30);
  EXPECT_EQ(cam.height, 20);
  EXPECT_EQ(cam.params, (std::vector<double>{25, 26, 15.5, 10.5}));
  ASSERT_EQ(m.images.size(), 1u);
  EXPECT_EQ(m.images[0].name, "view_a.png");
  EXPECT_EQ(m.images[0].camera_id, 7);
  EXPECT_EQ(m.images[0].point3d_ids, (std::vector<int64_t>{9, -1}));
  EXPECT_EQ(m.images[0].xys[1][0], 3.5);
  ASSERT_EQ(m.points.size(), 1u);
  EXPECT_EQ(m.points[0].point3d_id, 9);
  EXPECT_EQ(m.points[0].xyz.y, -0.5);
  EXPECT_EQ(m.points[0].rgb, (std::array<uint8_t, 3>{200, 100, 50}));
  EXPECT_EQ(m.points[0].track, (std::vector<std::pair<int, int>>{{5, 0}}));

  // q = (0.5, 0.5, 0.5, 0.5) is the cyclic permutation x->y->z->x:
  // R = [[0,0,1],[1,0,0],[0,1,0]]; camera point = R p + t.
  core::Camera camera = colmap_camera(m, m.images[0]);
  core::Vec3 pc = camera.world_to_camera.transform_point({1, 2, 3});
  EXPECT_NEAR(pc.x, 3 + 1, 1e-12);
  EXPECT_NEAR(pc.y, 1 + 2, 1e-12);
  EXPECT_NEAR(pc.z, 2 + 3, 1e-12);
  EXPECT_EQ(camera.intrinsics.fx, 25);
  EXPECT_EQ(camera.intrinsics.cy, 10.5);
  EXPECT_EQ(camera.intrinsics.width, 30);
}

TEST(Colmap, IntrinsicsOfEachModel) {
  ColmapCamera c{1, "SIMPLE_PINHOLE", 8, 6, {10, 4, 3}};
  core::Intrinsics k = colmap_intrinsics(c);
  EXPECT_EQ(k.fx, 10);
  EXPECT_EQ(k.fy, 10);
  EXPECT_EQ(k.cx, 4);
  EXPECT_FALSE(k.has_distortion());
  c = {1, "OPENCV", 8, 6, {10, 11, 4, 3, 0.1, 0.2, 0.3, 0.4}};
  k = colmap_intrinsics(c);
  EXPECT_EQ(k.fy, 11);
  EXPECT_EQ(k.k1, 0.1);
  EXPECT_EQ(k.k2, 0.2);
  EXPECT_EQ(k.p1, 0.3);
  EXPECT_EQ(k.p2, 0.4);
  c = {1, "SIMPLE_RADIAL", 8, 6, {10, 4, 3, -0.05}};
  EXPECT_EQ(colmap_intrinsics(c).k1, -0.05);
  c = {1, "RADIAL", 8, 6, {10, 4, 3, -0.05, 0.01}};
  EXPECT_EQ(colmap_intrinsics(c).k2, 0.01);
  c = {2, "PINHOLE", 8, 6, {10, 4, 3}};
  EXPECT_TRUE(contains(error_of([&] { colmap_intrinsics(c); }), "needs 4 parameters, found 3"));
  c = {2, "FULL_OPENCV", 8, 6, {10, 11, 4, 3, 0.1, 0.2, 0.3, 0.4, 0.5, 0, 0, 0}};
  EXPECT_EQ(colmap_intrinsics(c).k3, 0.5);
  c.params[9] = 0.01;  // k4: a rational term
  EXPECT_TRUE(contains(error_of([&] { colmap_intrinsics(c); }), "rational terms"));
  c = {2, "RADIAL_FISHEYE", 8, 6, {10, 4, 3, 0.02, -0.001}};
  k = colmap_intrinsics(c);
  EXPECT_TRUE(k.fisheye);
  EXPECT_EQ(k.fy, 10);
  EXPECT_EQ(k.k2, -0.001);
  c = {2, "FOV", 8, 6, {10, 11, 4, 3, 0.9}};
  EXPECT_TRUE(contains(error_of([&] { colmap_intrinsics(c); }), "unsupported camera model"));
}

// Every lens model ddhgs reads survives both file formats with its
// parameters, and intrinsics -> colmap_camera_of -> intrinsics is exact.
TEST(Colmap, LensModelsRoundTripBothFormats) {
  ColmapModel m;
  m.cameras[1] = {1, "SIMPLE_RADIAL", 64, 48, {50.5, 32.1, 23.9, -0.071}};
  m.cameras[2] = {2, "RADIAL", 64, 48, {50.5, 32.1, 23.9, -0.071, 0.0123}};
  m.cameras[3] = {3, "OPENCV", 64, 48, {50.5, 51, 32.1, 23.9, -0.07, 0.01, 1e-3, -2e-3}};
  m.cameras[4] = {
      4, "FULL_OPENCV", 64, 48, {50.5, 51, 32.1, 23.9, -0.07, 0.01, 1e-3, -2e-3, 0.004, 0, 0, 0}};
  m.cameras[5] = {5, "OPENCV_FISHEYE", 64, 48, {50.5, 51, 32.1, 23.9, 0.03, -0.004, 1e-3, -1e-4}};
  m.cameras[6] = {6, "SIMPLE_RADIAL_FISHEYE", 64, 48, {50.5, 32.1, 23.9, 0.03}};
  m.cameras[7] = {7, "RADIAL_FISHEYE", 64, 48, {50.5, 32.1, 23.9, 0.03, -0.004}};
  fs::path dir = test::temp_dir("colmap_lenses");
  write_colmap_binary(dir / "bin", m);
  write_colmap_text(dir / "txt", m);
  for (const char* format : {"bin", "txt"}) {
    ColmapModel back = read_colmap(dir / format);
    ASSERT_EQ(back.cameras.size(), m.cameras.size()) << format;
    for (const auto& [id, camera] : m.cameras) {
      EXPECT_EQ(back.cameras.at(id).model, camera.model) << format;
      EXPECT_EQ(back.cameras.at(id).params, camera.params) << format << " " << camera.model;
    }
  }
  for (const auto& [id, camera] : m.cameras) {
    core::Intrinsics k = colmap_intrinsics(camera);
    EXPECT_TRUE(k.has_distortion()) << camera.model;
    ColmapCamera again = colmap_camera_of(k);
    again.camera_id = id;
    EXPECT_TRUE(colmap_intrinsics(again) == k) << camera.model << " -> " << again.model;
  }
  core::Intrinsics k = colmap_intrinsics(m.cameras[3]);
  k.k4 = 0.001;  // nerfstudio's r^8 term: no COLMAP model has it
  EXPECT_TRUE(contains(error_of([&] { colmap_camera_of(k); }), "no COLMAP model holds it"));
}

TEST(Colmap, TruncatedBinaryFiles) {
  fs::path dir = test::temp_dir("colmap_truncated");
  write_colmap_binary(dir, sample_model());
  for (const char* name : {"cameras.bin", "images.bin", "points3D.bin"}) {
    fs::path file = dir / name;
    std::string bytes = read_file(file);
    write_file_atomically(file, bytes.substr(0, bytes.size() - 5));
    std::string what = error_of([&] { read_colmap(dir); });
    EXPECT_TRUE(contains(what, file.string())) << what;
    EXPECT_TRUE(contains(what, "truncated")) << what;
    write_file_atomically(file, bytes);
  }
  // An empty file, and a corrupt count far beyond the file size.
  write_file_atomically(dir / "images.bin", "");
  EXPECT_TRUE(contains(error_of([&] { read_colmap(dir); }), "images.bin"));
  std::string huge(8, '\xff');
  write_file_atomically(dir / "points3D.bin", huge + std::string(40, '\0'));
  write_colmap_binary(dir / "ok", sample_model());
  fs::copy_file(dir / "ok" / "images.bin", dir / "images.bin",
                fs::copy_options::overwrite_existing);
  std::string what = error_of([&] { read_colmap(dir); });
  EXPECT_TRUE(contains(what, "points3D.bin") && contains(what, "exceeds the file size")) << what;
}

TEST(Colmap, UnsupportedCameraModels) {
  fs::path dir = test::temp_dir("colmap_models");
  write_file_atomically(dir / "cameras.txt",
                        "# comment\n1 THIN_PRISM_FISHEYE 10 10 1 2 3 4 5 6 7 8 9 10 11 12\n");
  write_file_atomically(dir / "images.txt", "");
  std::string what = error_of([&] { read_colmap(dir); });
  EXPECT_TRUE(contains(what, "cameras.txt") && contains(what, "THIN_PRISM_FISHEYE")) << what;
  EXPECT_TRUE(contains(what, "unsupported camera model")) << what;

  write_file_atomically(dir / "cameras.txt", "1 MADE_UP 10 10 1 2 3\n");
  EXPECT_TRUE(contains(error_of([&] { read_colmap(dir); }), "MADE_UP"));

  // Binary: model id 42 is unknown to COLMAP.
  ColmapModel m = sample_model();
  write_colmap_binary(dir / "bin", m);
  std::string bytes = read_file(dir / "bin" / "cameras.bin");
  int32_t bad = 42;
  std::memcpy(&bytes[8 + 4], &bad, 4);
  write_file_atomically(dir / "bin" / "cameras.bin", bytes);
  what = error_of([&] { read_colmap(dir / "bin"); });
  EXPECT_TRUE(contains(what, "cameras.bin") && contains(what, "id 42")) << what;
}

TEST(Colmap, MalformedTextNamesLine) {
  fs::path dir = test::temp_dir("colmap_text_bad");
  write_file_atomically(dir / "cameras.txt", "# c\n\n1 PINHOLE 10 10 5 5 5\n");
  write_file_atomically(dir / "images.txt", "");
  std::string what = error_of([&] { read_colmap(dir); });
  EXPECT_TRUE(contains(what, "cameras.txt: line 3") && contains(what, "camera parameter")) << what;

  write_file_atomically(dir / "cameras.txt", "1 PINHOLE 10 10 5 5 5 5 6\n");
  EXPECT_TRUE(contains(error_of([&] { read_colmap(dir); }), "more parameters"));

  write_file_atomically(dir / "cameras.txt", "1 PINHOLE 10 10 5 5 5 5\n");
  write_file_atomically(dir / "images.txt", "1 1 0 0 0 0 0 zero 1 a.png\n\n");
  what = error_of([&] { read_colmap(dir); });
  EXPECT_TRUE(contains(what, "images.txt: line 1") && contains(what, "translation")) << what;

  write_file_atomically(dir / "images.txt", "1 1 0 0 0 0 0 0 1 a.png\n1 2\n");
  EXPECT_TRUE(contains(error_of([&] { read_colmap(dir); }), "images.txt: line 2"));

  fs::remove(dir / "cameras.txt");
  EXPECT_TRUE(contains(error_of([&] { read_colmap(dir); }), "expected a COLMAP model"));
}

TEST(Colmap, ImageWithoutCameraOrZeroQuaternion) {
  ColmapModel m = sample_model();
  m.images[0].camera_id = 99;
  EXPECT_TRUE(contains(error_of([&] { colmap_camera(m, m.images[0]); }), "camera 99"));
  m.images[1].qvec = {0, 0, 0, 0};
  EXPECT_TRUE(contains(error_of([&] { colmap_camera(m, m.images[1]); }), "quaternion"));
}

TEST(Colmap, WritersRejectInconsistentModels) {
  fs::path dir = test::temp_dir("colmap_write_bad");
  ColmapModel m = sample_model();
  m.cameras[1].params.pop_back();
  EXPECT_TRUE(contains(error_of([&] { write_colmap_binary(dir / "a", m); }), "camera 1"));
  m = sample_model();
  m.images[1].point3d_ids.pop_back();
  EXPECT_TRUE(contains(error_of([&] { write_colmap_text(dir / "b", m); }), "frame 1.png"));
  EXPECT_FALSE(fs::exists(dir / "a"));
  EXPECT_FALSE(fs::exists(dir / "b"));
}

TEST(Colmap, FindsModelFolders) {
  fs::path root = test::temp_dir("colmap_find");
  EXPECT_FALSE(find_colmap_model(root).has_value());
  write_colmap_text(root / "colmap" / "sparse" / "0", sample_model());
  EXPECT_EQ(*find_colmap_model(root), root / "colmap" / "sparse" / "0");
  write_colmap_binary(root / "sparse" / "0", sample_model());
  EXPECT_EQ(*find_colmap_model(root), root / "sparse" / "0");
}

}  // namespace
}  // namespace ddhgs::io
