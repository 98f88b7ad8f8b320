// A rig scene's metadata in transforms.json ("rig", frames' "rig_camera"),
// the corrections file, and the rotation-vector helpers.
#include <gtest/gtest.h>

#include "core/error.h"
#include "io/files/atomic_file.h"
#include "io/rig/rig_capture.h"
#include "io/rig/rig_layout.h"
#include "io/transforms/transforms.h"
#include "support/test_support.h"

namespace ddhgs::io {
namespace {

namespace fs = std::filesystem;

TransformsFile rig_file() {
  TransformsFile file;
  file.wavelengths_nm = {475, 842};
  file.rig = TransformsRig{0, 0.5, {{0, "Blue", {0.1, -0.2, 0.3}}, {3, "NIR", {}}}};
  for (int k : {0, 3}) {
    TransformsFrame f;
    f.hyperspectral_file_path = "bands/IMG_0000_" + std::to_string(k) + ".npy";
    f.intrinsics = {50, 50, 16, 12, 32, 24};
    f.bands = {k == 0 ? 0 : 1};
    f.rig_camera = k;
    file.frames.push_back(f);
  }
  return file;
}

TEST(RigLayout, TransformsKeepTheRigAndEachFramesCamera) {
  const fs::path path = test::temp_dir("rig_layout") / "transforms.json";
  write_transforms(path, rig_file());
  const TransformsFile back = read_transforms(path);
  ASSERT_TRUE(back.rig.has_value());
  EXPECT_EQ(back.rig->reference_camera, 0);
  EXPECT_EQ(back.rig->unit_m, 0.5);
  ASSERT_EQ(back.rig->cameras.size(), 2u);
  EXPECT_EQ(back.rig->cameras[0].band, "Blue");
  EXPECT_EQ(back.rig->cameras[0].relatives_deg, (std::vector<double>{0.1, -0.2, 0.3}));
  EXPECT_TRUE(back.rig->cameras[1].relatives_deg.empty());
  EXPECT_EQ(back.frames[0].rig_camera, 0);
  EXPECT_EQ(back.frames[1].rig_camera, 3);
  // The turn from the reference camera (0) to camera 3 undoes camera 0's.
  const core::Mat3 turn = back.rig->turn(3);
  const core::Mat3 want = rig_relative_rotation({0.1, -0.2, 0.3}).transposed();
  for (int i = 0; i < 9; ++i) EXPECT_NEAR(turn.m[size_t(i)], want.m[size_t(i)], 1e-15);

  TransformsFile bad = rig_file();
  bad.frames[1].rig_camera = 4;
  write_transforms(path, bad);
  EXPECT_THROW(
      {
        try {
          read_transforms(path);
        } catch (const core::Error& e) {
          EXPECT_NE(std::string(e.what()).find("frames[1].rig_camera"), std::string::npos)
              << e.what();
          throw;
        }
      },
      core::Error);
}

TEST(RigLayout, RotationVectorsRoundTrip) {
  for (const core::Vec3& r :
       {core::Vec3{0.01, -0.02, 0.005}, core::Vec3{1.0, 0.5, -2.0}, core::Vec3{0, 0, 0}}) {
    const core::Vec3 back = rotation_vector(rotation_from_vector(r));
    EXPECT_NEAR((back - r).norm(), 0, 1e-12);
  }
  // A quarter turn about z takes x to y.
  const core::Vec3 y =
      rotation_from_vector({0, 0, 3.14159265358979323846 / 2}) * core::Vec3{1, 0, 0};
  EXPECT_NEAR((y - core::Vec3{0, 1, 0}).norm(), 0, 1e-15);
}

TEST(RigLayout, CorrectionsFileRoundTripsAndRefusesMalformedOnes) {
  const fs::path dir = test::temp_dir("rig_corrections");
  TransformsRig rig{0, 0.5, {{0, "Blue", {}}, {3, "NIR", {}}}};
  const std::map<int, RigCorrection> corrections = {{3, {{0.01, -0.02, 0.003}, {0.1, 0.2, -0.05}}}};
  write_rig_corrections(dir / "rig_corrections.json", rig, corrections);
  const std::map<int, RigCorrection> back = read_rig_corrections(dir / "rig_corrections.json");
  ASSERT_EQ(back.size(), 1u);
  EXPECT_EQ((back.at(3).rotation_rad - corrections.at(3).rotation_rad).norm(), 0);
  EXPECT_EQ((back.at(3).offset - corrections.at(3).offset).norm(), 0);
  EXPECT_NE(read_file(dir / "rig_corrections.json").find("\"offset_cm\""), std::string::npos);
  EXPECT_EQ(describe_rig_correction(rig, 3, corrections.at(3)).substr(0, 27),
            "camera 3 (NIR): turned 1.29");
  write_file_atomically(dir / "bad.json", "{\"cameras\": [{\"rig_camera\": 3, \"offset\": [1]}]}");
  EXPECT_THROW(read_rig_corrections(dir / "bad.json"), core::Error);
}

// A rig's known lever arms, written by hand: offsets in cm (converted by
// the scene's unit), no rotation; refused where the unit is unknown.
TEST(RigLayout, LeverArmsInCentimetresNeedTheScenesUnit) {
  const fs::path dir = test::temp_dir("rig_lever_arms");
  const fs::path arms = dir / "lever_arms.json";
  write_file_atomically(arms,
                        "{\"cameras\": [{\"rig_camera\": 2, \"offset_cm\": [4, -3, 0.5]},"
                        " {\"rig_camera\": 5, \"offset_cm\": [0, 10, 0],"
                        " \"rotation_rad\": [0.001, 0, 0]}]}");
  const std::map<int, RigCorrection> back = read_rig_corrections(arms, 0.5);  // 0.5 m a unit
  ASSERT_EQ(back.size(), 2u);
  EXPECT_NEAR((back.at(2).offset - core::Vec3{0.08, -0.06, 0.01}).norm(), 0, 1e-15);
  EXPECT_EQ(back.at(2).rotation_rad.norm(), 0);
  EXPECT_NEAR((back.at(5).offset - core::Vec3{0, 0.2, 0}).norm(), 0, 1e-15);
  EXPECT_EQ(back.at(5).rotation_rad.x, 0.001);
  try {
    read_rig_corrections(arms);
    ADD_FAILURE() << "offset_cm read without the scene's unit";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("lever_arms.json"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("unit is unknown"), std::string::npos) << e.what();
  }
  // "offset" (scene units, exact) wins over "offset_cm" (a run's own file).
  write_file_atomically(arms,
                        "{\"cameras\": [{\"rig_camera\": 2, \"offset\": [1, 2, 3],"
                        " \"offset_cm\": [7, 7, 7]}]}");
  EXPECT_EQ((read_rig_corrections(arms, 0.5).at(2).offset - core::Vec3{1, 2, 3}).norm(), 0);
  write_file_atomically(arms,
                        "{\"cameras\": [{\"rig_camera\": 2, \"offset_cm\": [1, 2, 3]},"
                        " {\"rig_camera\": 2, \"offset_cm\": [1, 2, 3]}]}");
  EXPECT_THROW(read_rig_corrections(arms, 1.0), core::Error);
  write_file_atomically(arms, "{\"cameras\": [{\"rig_camera\": 2}]}");
  EXPECT_THROW(read_rig_corrections(arms, 1.0), core::Error);
}

}  // namespace
}  // namespace ddhgs::io
