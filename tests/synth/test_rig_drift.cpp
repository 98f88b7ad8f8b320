// The synthetic rig's drift (--rig-perturb-deg, --rig-offset-cm): the
// metadata keeps the factory RigRelatives, the truth's band cameras sit
// where the drift puts them, and synth.json says by how much; the truth is
// the factory placement corrected as io::corrected_band_camera corrects it.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "io/files/atomic_file.h"
#include "io/rig/rig_capture.h"
#include "io/rig/rig_layout.h"
#include "io/transforms/transforms.h"
#include "support/test_support.h"
#include "synth/generate.h"
#include "synth/rig_scene.h"

namespace ddhgs::synth {
namespace {

namespace fs = std::filesystem;
constexpr double kDeg = 3.14159265358979323846 / 180;

core::Vec3 vec(const nlohmann::json& v) {
  return {v[0].get<double>(), v[1].get<double>(), v[2].get<double>()};
}

TEST(RigDrift, MetadataKeepsTheFactoryRotationsWhileTheTruthDrifts) {
  SynthConfig config = preset_config("rig");
  config.width = 24;
  config.height = 18;
  config.views = 3;
  config.supersample = 1;
  config.points = 30;
  config.rig_perturb_deg = 1;
  config.rig_offset_cm = 10;
  const fs::path out = test::temp_dir("rig_drift") / "rig";
  write_synthetic_scene(config, out, false);

  const std::vector<RigBandCamera> factory = rededge_rig();
  for (const io::RigCapture& capture : io::read_rig_captures(out / "captures"))
    for (const io::RigBandImage& b : capture.bands)
      EXPECT_EQ(b.rig_relatives_deg, factory[size_t(b.rig_index - 1)].relatives_deg) << b.file;

  const nlohmann::json synth = nlohmann::json::parse(io::read_file(out / "synth.json"));
  EXPECT_EQ(synth["unit_m"].get<double>(), 1.0);
  std::map<int, io::RigCorrection> drift;
  for (const nlohmann::json& c : synth["cameras"]) {
    const int index = c["rig_index"].get<int>();
    const io::RigCorrection d{vec(c["true_rotation_error_deg"]) * kDeg,
                              vec(c["true_offset_cm"]) * 0.01};
    drift[index] = d;
    const double want_deg = index == 1 ? 0 : 1, want_m = index == 1 ? 0 : 0.1;
    EXPECT_NEAR(d.rotation_rad.norm() / kDeg, want_deg, 1e-9) << index;
    EXPECT_NEAR(d.offset.norm(), want_m, 1e-12) << index;
    EXPECT_EQ(d.offset.z, 0) << "across the rig's face";
  }

  const io::TransformsFile truth = io::read_transforms(out / "truth" / "transforms.json");
  ASSERT_TRUE(truth.rig.has_value());
  EXPECT_EQ(truth.rig->reference_camera, 1);
  EXPECT_EQ(truth.rig->unit_m, 1.0);
  std::map<int, core::Mat4> body;  // camera 1's pose per capture
  ASSERT_EQ(truth.frames.size(), 15u);
  for (size_t f = 0; f < truth.frames.size(); ++f) {
    const io::TransformsFrame& frame = truth.frames[f];
    const core::Mat4 w2c = core::opengl_c2w_to_opencv_w2c(frame.camera_to_world_gl);
    if (frame.rig_camera == 1) body[int(f / 5)] = w2c;
  }
  double worst = 0, moved = 0;
  for (size_t f = 0; f < truth.frames.size(); ++f) {
    const io::TransformsFrame& frame = truth.frames[f];
    const core::Mat3 turn = truth.rig->turn(frame.rig_camera);
    core::Camera placed;  // where the factory rotation puts it
    placed.world_to_camera = core::Mat4::from(turn, {}) * body.at(int(f / 5));
    const core::Camera corrected =
        io::corrected_band_camera(placed, turn, drift.at(frame.rig_camera));
    const core::Mat4 w2c = core::opengl_c2w_to_opencv_w2c(frame.camera_to_world_gl);
    for (int i = 0; i < 16; ++i) {
      worst = std::max(worst, std::abs(w2c.m[size_t(i)] - corrected.world_to_camera.m[size_t(i)]));
      moved = std::max(moved, std::abs(w2c.m[size_t(i)] - placed.world_to_camera.m[size_t(i)]));
    }
  }
  EXPECT_LT(worst, 1e-9);
  EXPECT_GT(moved, 0.05);  // the drift is there
}

TEST(RigDrift, IsRefusedOutsideTheRigPresets) {
  SynthConfig config = preset_config("demo");
  config.rig_perturb_deg = 1;
  EXPECT_THROW(validate(config), core::Error);
}

}  // namespace
}  // namespace ddhgs::synth
