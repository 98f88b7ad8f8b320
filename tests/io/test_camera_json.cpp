// Camera JSON files: known content, round trip, and every kind of bad input.
#include <gtest/gtest.h>

#include <fstream>

#include "core/error.h"
#include "io/transforms/camera_json.h"
#include "support/test_support.h"

namespace ddhgs::io {
namespace {
namespace fs = std::filesystem;

const char* kIdentityRows = "[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]";

fs::path write_json(const fs::path& dir, const std::string& name, const std::string& text) {
  std::ofstream(dir / name) << text;
  return dir / name;
}

std::string camera_text(const std::string& matrix, const std::string& extra = "") {
  return R"({"width": 64, "height": 48, "fx": 50.5, "fy": 51, "cx": 32, "cy": 24.25, )" + extra +
         R"("world_to_camera": )" + matrix + "}";
}

TEST(CameraJson, ReadsKnownContent) {
  auto dir = test::temp_dir("camera_json_known");
  // A camera at (0, 0, -5) looking along +z: t = -R c = (0, 0, 5).
  auto path = write_json(dir, "cam.json",
                         camera_text("[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 5], [0, 0, 0, 1]]"));
  auto camera = read_camera_json(path);
  EXPECT_EQ(camera.intrinsics.width, 64);
  EXPECT_EQ(camera.intrinsics.height, 48);
  EXPECT_EQ(camera.intrinsics.fx, 50.5);
  EXPECT_EQ(camera.intrinsics.fy, 51);
  EXPECT_EQ(camera.intrinsics.cx, 32);
  EXPECT_EQ(camera.intrinsics.cy, 24.25);
  EXPECT_EQ(camera.center().z, -5);
  // Three rows are completed with 0 0 0 1.
  auto short_path =
      write_json(dir, "short.json", camera_text("[[0, -1, 0, 1], [1, 0, 0, 2], [0, 0, 1, 3]]"));
  auto short_camera = read_camera_json(short_path);
  EXPECT_EQ(short_camera.world_to_camera(0, 1), -1);
  EXPECT_EQ(short_camera.world_to_camera(3, 3), 1);
}

TEST(CameraJson, RoundTripsExactly) {
  auto dir = test::temp_dir("camera_json_round_trip");
  core::Camera camera;
  camera.intrinsics = {123.456789012345, 98.7654321, 31.9, 24.1, 64, 48};
  camera.world_to_camera = core::look_at({1.1, -2.2, 3.3}, {0.1, 0.2, 0.3}, {0, 0, 1});
  write_camera_json(dir / "cam.json", camera);
  auto back = read_camera_json(dir / "cam.json");
  EXPECT_EQ(back.intrinsics.fx, camera.intrinsics.fx);
  EXPECT_EQ(back.intrinsics.fy, camera.intrinsics.fy);
  EXPECT_EQ(back.intrinsics.width, 64);
  EXPECT_EQ(back.world_to_camera.m, camera.world_to_camera.m);
}

TEST(CameraJson, BadFilesNameTheFileAndTheProblem) {
  auto dir = test::temp_dir("camera_json_bad");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"{\"width\": 64,", "not valid JSON"},
      {"[1, 2]", "JSON object"},
      {R"({"width": 64, "height": 48, "fx": 50, "fy": 50, "cx": 32, "world_to_camera": )" +
           std::string(kIdentityRows) + "}",
       "missing key \"cy\""},
      {R"({"width": "64", "height": 48, "fx": 50, "fy": 50, "cx": 32, "cy": 24})",
       "\"width\" must be a number"},
      {R"({"width": 64.5, "height": 48, "fx": 50, "fy": 50, "cx": 32, "cy": 24})", "whole number"},
      {R"({"width": 64, "height": 0, "fx": 50, "fy": 50, "cx": 32, "cy": 24})", "whole number"},
      {R"({"width": 64, "height": 48, "fx": -50, "fy": 50, "cx": 32, "cy": 24, "world_to_camera": )" +
           std::string(kIdentityRows) + "}",
       "positive"},
      {camera_text("[[1, 0, 0], [0, 1, 0], [0, 0, 1]]"), "4 numbers"},
      {camera_text("[[1, 0, 0, 0], [0, 1, 0, 0]]"), "4 x 4"},
      {camera_text("{\"R\": 1}"), "4 x 4"},
      {camera_text("[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, \"a\"], [0, 0, 0, 1]]"),
       "world_to_camera[2][3]\" must be a number"},
      {camera_text("[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 0], [0, 0, 0, 1]]"), "not invertible"},
      {camera_text("[[2, 0, 0, 0], [0, 2, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1]]"), "rigid"},
      {camera_text("[[-1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]"), "rigid"},
      {camera_text("[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]]"), "last row"},
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    auto path = write_json(dir, "bad" + std::to_string(i) + ".json", cases[i].first);
    try {
      read_camera_json(path);
      ADD_FAILURE() << "no error for case " << i;
    } catch (const core::Error& e) {
      std::string what = e.what();
      EXPECT_EQ(what.rfind(path.string() + ": ", 0), 0u) << what;
      EXPECT_NE(what.find(cases[i].second), std::string::npos) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
  }
  EXPECT_THROW(read_camera_json(dir / "absent.json"), core::Error);
}

}  // namespace
}  // namespace ddhgs::io
