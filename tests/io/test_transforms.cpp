// transforms.json: round trips through the writer and malformed files.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "core/error.h"
#include "io/files/atomic_file.h"
#include "io/transforms/transforms.h"
#include "support/test_support.h"

namespace ddhgs::io {
namespace {
namespace fs = std::filesystem;

core::Intrinsics intrinsics(double f, int w, int h) {
  core::Intrinsics k;
  k.fx = f;
  k.fy = f * 1.01;
  k.cx = w * 0.5 + 1.25;
  k.cy = h * 0.5 - 0.75;
  k.width = w;
  k.height = h;
  return k;
}

TransformsFrame frame(int i, const core::Intrinsics& k) {
  TransformsFrame f;
  f.file_path = "images/r_" + std::to_string(i) + ".png";
  f.hyperspectral_file_path = "hyperspectral/r_" + std::to_string(i) + ".npy";
  f.intrinsics = k;
  core::Vec3 eye{2.0 * std::cos(i * 0.7), 2.0 * std::sin(i * 0.7), 0.3 + 0.1 * i};
  f.camera_to_world_gl = core::opencv_w2c_to_opengl_c2w(core::look_at(eye, {0, 0, 0.1}, {0, 0, 1}));
  return f;
}

void expect_near(const core::Mat4& a, const core::Mat4& b, double tol) {
  for (int i = 0; i < 16; ++i) EXPECT_NEAR(a.m[size_t(i)], b.m[size_t(i)], tol) << "entry " << i;
}

// Exact: the writer prints doubles with 17 significant digits.
void expect_same_intrinsics(const core::Intrinsics& a, const core::Intrinsics& b) {
  EXPECT_TRUE(a == b) << "fx " << a.fx << " / " << b.fx << ", k1 " << a.k1 << " / " << b.k1
                      << ", fisheye " << a.fisheye << " / " << b.fisheye;
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream(path) << text;
}

// Reading must throw core::Error whose one-line message names the file and
// every given fragment.
void expect_error(const fs::path& path, const std::vector<std::string>& fragments) {
  try {
    read_transforms(path);
    ADD_FAILURE() << "no error for " << path;
  } catch (const core::Error& e) {
    std::string what = e.what();
    EXPECT_NE(what.find(path.string()), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    for (const auto& f : fragments) EXPECT_NE(what.find(f), std::string::npos) << what;
  }
}

TEST(Transforms, RoundTripSharedIntrinsics) {
  fs::path dir = test::temp_dir("transforms_roundtrip");
  TransformsFile file;
  core::Intrinsics k = intrinsics(500.5, 64, 48);
  k.k1 = -0.01;
  k.p2 = 0.002;
  for (int i = 0; i < 4; ++i) file.frames.push_back(frame(i, k));
  file.wavelengths_nm = {400.5, 500, 600.25};
  file.ply_file_path = "points.ply";
  file.scale = 4095;
  file.train_files = {"images/r_0.png", "images/r_1.png", "images/r_3.png"};
  file.test_files = {"images/r_2.png"};
  write_transforms(dir / "transforms.json", file);

  TransformsFile back = read_transforms(dir / "transforms.json");
  ASSERT_EQ(back.frames.size(), file.frames.size());
  for (size_t i = 0; i < file.frames.size(); ++i) {
    const auto& a = file.frames[i];
    const auto& b = back.frames[i];
    EXPECT_EQ(a.file_path, b.file_path);
    EXPECT_EQ(a.hyperspectral_file_path, b.hyperspectral_file_path);
    expect_same_intrinsics(a.intrinsics, b.intrinsics);
    expect_near(a.camera_to_world_gl, b.camera_to_world_gl, 1e-12);
    expect_near(core::opengl_c2w_to_opencv_w2c(a.camera_to_world_gl),
                core::opengl_c2w_to_opencv_w2c(b.camera_to_world_gl), 1e-9);
  }
  EXPECT_EQ(back.wavelengths_nm, file.wavelengths_nm);
  EXPECT_EQ(back.ply_file_path, "points.ply");
  ASSERT_TRUE(back.scale.has_value());
  EXPECT_EQ(*back.scale, 4095);
  EXPECT_EQ(back.train_files, file.train_files);
  EXPECT_EQ(back.test_files, file.test_files);

  // Shared intrinsics are written once at the top level, as nerfstudio does.
  std::string text = read_file(dir / "transforms.json");
  EXPECT_EQ(text.find("\"fl_x\""), text.rfind("\"fl_x\""));
}

TEST(Transforms, RoundTripPerFrameIntrinsics) {
  fs::path dir = test::temp_dir("transforms_per_frame");
  TransformsFile file;
  file.frames.push_back(frame(0, intrinsics(400, 32, 24)));
  file.frames.push_back(frame(1, intrinsics(800, 64, 48)));
  file.frames[1].hyperspectral_file_path.clear();
  write_transforms(dir / "transforms.json", file);
  TransformsFile back = read_transforms(dir / "transforms.json");
  ASSERT_EQ(back.frames.size(), 2u);
  expect_same_intrinsics(back.frames[0].intrinsics, file.frames[0].intrinsics);
  expect_same_intrinsics(back.frames[1].intrinsics, file.frames[1].intrinsics);
  EXPECT_TRUE(back.frames[1].hyperspectral_file_path.empty());
  EXPECT_FALSE(back.scale.has_value());
}

TEST(Transforms, LensModelsAndAppliedTransformRoundTrip) {
  fs::path dir = test::temp_dir("transforms_lenses");
  TransformsFile file;
  core::Intrinsics opencv = intrinsics(300, 64, 48);
  opencv.k1 = -0.21;
  opencv.k2 = 0.043;
  opencv.k3 = -0.0071;
  opencv.k4 = 0.0009;
  opencv.p1 = 1.0 / 3000;
  opencv.p2 = -0.0017;
  core::Intrinsics fisheye = intrinsics(200, 64, 48);
  fisheye.fisheye = true;
  fisheye.k1 = 0.031;
  fisheye.k2 = -0.0042;
  fisheye.k3 = 0.0011;
  fisheye.k4 = -0.00013;
  core::Intrinsics pinhole = intrinsics(250, 64, 48);
  file.frames = {frame(0, opencv), frame(1, fisheye), frame(2, pinhole)};
  core::Mat4 applied;  // nerfstudio's axis swap: (x, y, z) -> (x, z, -y)
  applied.m = {1, 0, 0, 0.5, 0, 0, 1, -1, 0, -1, 0, 2, 0, 0, 0, 1};
  file.applied_transform = applied;
  write_transforms(dir / "transforms.json", file);
  TransformsFile back = read_transforms(dir / "transforms.json");
  ASSERT_EQ(back.frames.size(), 3u);
  for (size_t i = 0; i < 3; ++i)
    expect_same_intrinsics(back.frames[i].intrinsics, file.frames[i].intrinsics);
  ASSERT_TRUE(back.applied_transform.has_value());
  expect_near(*back.applied_transform, applied, 0);

  std::string text = read_file(dir / "transforms.json");
  for (const char* model : {"\"OPENCV\"", "\"OPENCV_FISHEYE\"", "\"PINHOLE\""})
    EXPECT_NE(text.find(model), std::string::npos) << model;
}

TEST(Transforms, DefaultsAndPerFrameOverrides) {
  fs::path dir = test::temp_dir("transforms_defaults");
  write_text(dir / "transforms.json", R"({
    "fl_x": 100, "w": 40, "h": 30, "camera_model": "OPENCV", "k1": 0.5,
    "frames": [
      {"file_path": "a.png", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]},
      {"file_path": "b.png", "fl_x": 200, "cx": 7,
       "transform_matrix": [[1,0,0,1],[0,1,0,2],[0,0,1,3]]}
    ]})");
  TransformsFile file = read_transforms(dir / "transforms.json");
  ASSERT_EQ(file.frames.size(), 2u);
  const auto& a = file.frames[0].intrinsics;
  EXPECT_EQ(a.fx, 100);
  EXPECT_EQ(a.fy, 100);  // fl_y defaults to fl_x
  EXPECT_EQ(a.cx, 20);   // principal point defaults to the image centre
  EXPECT_EQ(a.cy, 15);
  EXPECT_EQ(a.k1, 0.5);
  const auto& b = file.frames[1].intrinsics;
  EXPECT_EQ(b.fx, 200);
  EXPECT_EQ(b.cx, 7);
  EXPECT_EQ(b.cy, 15);
  // A 3x4 matrix gets the constant last row.
  EXPECT_EQ(file.frames[1].camera_to_world_gl(0, 3), 1);
  EXPECT_EQ(file.frames[1].camera_to_world_gl(2, 3), 3);
  EXPECT_EQ(file.frames[1].camera_to_world_gl(3, 3), 1);
  EXPECT_TRUE(file.wavelengths_nm.empty());
}

TEST(Transforms, ScaledRotationRecoversTheCamera) {
  fs::path dir = test::temp_dir("transforms_scaled");
  TransformsFrame f = frame(3, intrinsics(300, 32, 32));
  core::Mat4 scaled = f.camera_to_world_gl;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) scaled(r, c) *= 2.75;
  TransformsFile file;
  file.frames = {f};
  file.frames[0].camera_to_world_gl = scaled;
  write_transforms(dir / "transforms.json", file);
  TransformsFile back = read_transforms(dir / "transforms.json");
  expect_near(core::opengl_c2w_to_opencv_w2c(back.frames[0].camera_to_world_gl),
              core::opengl_c2w_to_opencv_w2c(f.camera_to_world_gl), 1e-9);
}

const char* kMatrix = R"([[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]])";

TEST(Transforms, MalformedFilesNameFileAndKey) {
  fs::path dir = test::temp_dir("transforms_bad");
  fs::path p = dir / "transforms.json";
  std::string intr = R"("fl_x": 100, "w": 40, "h": 30, )";

  write_text(p, "{" + intr + R"("frame": []})");
  expect_error(p, {"missing key \"frames\""});

  write_text(p, "{" + intr + R"("frames": {"a": 1}})");
  expect_error(p, {"frames", "expected an array"});

  write_text(p, "{" + intr + R"("frames": []})");
  expect_error(p, {"frames", "at least one frame"});

  write_text(p, "{" + intr + R"("frames": [{"file_path": "a.png"}]})");
  expect_error(p, {"frames[0]", "transform_matrix"});

  write_text(
      p,
      "{" + intr +
          R"("frames": [{"file_path": "a.png", "transform_matrix": [[1,0,0],[0,1,0],[0,0,1]]}]})");
  expect_error(p, {"frames[0].transform_matrix[0]", "expected 4 columns"});

  write_text(
      p, "{" + intr +
             R"("frames": [{"file_path": "a.png", "transform_matrix": [[1,0,0,0],[0,1,0,0]]}]})");
  expect_error(p, {"frames[0].transform_matrix", "4x4"});

  write_text(
      p,
      "{" + intr +
          R"("frames": [{"file_path": "a.png", "transform_matrix": [[1,0,0,"x"],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]})");
  expect_error(p, {"frames[0].transform_matrix[0][3]", "expected a number, found string"});

  write_text(
      p,
      std::string(
          R"({"fl_x": "100", "w": 40, "h": 30, "frames": [{"file_path": "a.png", "transform_matrix": )") +
          kMatrix + "}]}");
  expect_error(p, {"fl_x", "expected a number"});

  write_text(
      p, std::string(
             R"({"fl_x": 100, "h": 30, "frames": [{"file_path": "a.png", "transform_matrix": )") +
             kMatrix + "}]}");
  expect_error(p, {"frames[0]", "missing key \"w\""});

  // A size too large for an int (the fuzzer's find) is refused, not converted.
  write_text(
      p,
      std::string(
          R"({"fl_x": 100, "w": 5.5e20, "h": 30, "frames": [{"file_path": "a.png", "transform_matrix": )") +
          kMatrix + "}]}");
  expect_error(p, {"frames[0]", "at most 1048576"});

  write_text(p, "{" + intr + R"("frames": [{"transform_matrix": )" + kMatrix + "}]}");
  expect_error(p, {"frames[0]", "file_path"});

  write_text(
      p,
      "{" + intr +
          R"("camera_model": "EQUIRECTANGULAR", "frames": [{"file_path": "a.png", "transform_matrix": )" +
          kMatrix + "}]}");
  expect_error(p, {"unsupported camera model", "EQUIRECTANGULAR"});

  // Coefficients the named model cannot have.
  write_text(
      p,
      "{" + intr +
          R"("camera_model": "PINHOLE", "k1": 0.1, "frames": [{"file_path": "a.png", "transform_matrix": )" +
          kMatrix + "}]}");
  expect_error(p, {"frames[0]", "PINHOLE has no lens distortion"});
  write_text(
      p,
      "{" + intr +
          R"("camera_model": "OPENCV_FISHEYE", "p1": 0.01, "frames": [{"file_path": "a.png", "transform_matrix": )" +
          kMatrix + "}]}");
  expect_error(p, {"frames[0]", "no tangential terms"});

  write_text(
      p,
      "{" + intr +
          R"("wavelengths": [400, "500"], "frames": [{"file_path": "a.png", "transform_matrix": )" +
          kMatrix + "}]}");
  expect_error(p, {"wavelengths[1]"});

  write_text(p,
             "{" + intr + R"("frames": [{"file_path": 5, "transform_matrix": )" + kMatrix + "}]}");
  expect_error(p, {"frames[0].file_path", "expected a string"});

  write_text(p, "{" + intr + R"("frames": [)");
  expect_error(p, {"not valid JSON"});

  write_text(p, "[1, 2]");
  expect_error(p, {"expected a JSON object"});

  expect_error(dir / "absent" / "transforms.json", {});
}

TEST(Transforms, WriterIsAtomicAndRefusesEmpty) {
  fs::path dir = test::temp_dir("transforms_empty");
  EXPECT_THROW(write_transforms(dir / "transforms.json", TransformsFile{}), core::Error);
  EXPECT_FALSE(fs::exists(dir / "transforms.json"));
  EXPECT_TRUE(fs::is_empty(dir));
}

}  // namespace
}  // namespace ddhgs::io
