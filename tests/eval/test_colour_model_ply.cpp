// The colour model's PLY form (model/colour_model.h, io/ply/ply.h): a latent
// model's basis and mean survive the file bit for bit.
#include <gtest/gtest.h>

#include "core/error.h"
#include "eval/rgb_export.h"
#include "io/files/atomic_file.h"
#include "io/ply/ply.h"
#include "model/colour_fixtures.h"
#include "model/gaussians.h"
#include "support/test_support.h"

namespace ddhgs::test {
namespace {

using torch::Tensor;

TEST(ColourModel, PlyKeepsTheBasisAndRendersTheSame) {
  const core::Camera camera = test_core_camera(kWidth, kHeight);
  const model::Gaussians g = latent_scene(9);
  const Tensor background = torch::rand({9});
  const auto dir = temp_dir("colour_model_ply");
  const std::vector<double> wavelengths = {400, 450, 500, 550, 600, 650, 700, 750, 800};
  io::write_gaussian_ply(dir / "latent.ply", model::to_ply(g, wavelengths));
  const io::GaussianPly ply = io::read_gaussian_ply(dir / "latent.ply");
  EXPECT_EQ(ply.bands(), 9);
  EXPECT_EQ(ply.sh_dc.size(1), 3);
  EXPECT_TRUE(torch::equal(ply.basis, g.colour.basis));
  EXPECT_TRUE(torch::equal(ply.mean, g.colour.mean));
  model::Gaussians back = model::from_ply(ply);
  back.active_sh_degree = 1;
  EXPECT_TRUE(torch::equal(model::render_gaussians(back, camera, background).image,
                           model::render_gaussians(g, camera, background).image));

  // A band_basis line with a wrong count names the line.
  std::string text = io::read_file(dir / "latent.ply");
  const size_t at = text.find("comment band_basis ");
  ASSERT_NE(at, std::string::npos);
  text.insert(text.find('\n', at), " 1");
  io::write_file_atomically(dir / "bad.ply", text);
  try {
    io::read_gaussian_ply(dir / "bad.ply");
    FAIL() << "read a band_basis line of 5 numbers for 3 channels";
  } catch (const core::Error& e) {
    EXPECT_NE(std::string(e.what()).find("line 1 has 5 numbers; expected 4"), std::string::npos)
        << e.what();
  }
}

TEST(ColourModel, ExportMapsALatentModelAsItsPerBandEquivalent) {
  const model::Gaussians g = latent_scene(21);
  const std::vector<double> wavelengths = {420, 460, 500, 540, 580, 620, 660, 700, 740};
  const io::GaussianPly latent = model::to_ply(g, wavelengths);
  // The same colours with one SH set per band: B c for every coefficient, the
  // DC shifted by the mean less the per-band model's 0.5.
  io::GaussianPly per_band = latent;
  per_band.basis = per_band.mean = torch::Tensor();
  const Tensor B = latent.basis.to(torch::kFloat64);
  per_band.sh_dc = ((latent.sh_dc.to(torch::kFloat64) * model::kShC0).matmul(B.t()) +
                    latent.mean.to(torch::kFloat64) - 0.5) /
                   model::kShC0;
  per_band.sh_rest = torch::einsum("nc,gck->gnk", {B, latent.sh_rest.to(torch::kFloat64)});
  per_band.sh_dc = per_band.sh_dc.to(torch::kFloat32);
  per_band.sh_rest = per_band.sh_rest.to(torch::kFloat32);
  for (const eval::ColourMapping& mapping : {eval::cie_mapping(wavelengths, 9, true),
                                             eval::band_mapping(wavelengths, {460, 580, 700})}) {
    const io::GaussianPly a = eval::map_colours(latent, mapping);
    const io::GaussianPly b = eval::map_colours(per_band, mapping);
    EXPECT_LT(scaled_error(a.sh_dc, b.sh_dc), 1e-5) << mapping.description;
    EXPECT_LT(scaled_error(a.sh_rest, b.sh_rest), 1e-5) << mapping.description;
  }
}

}  // namespace
}  // namespace ddhgs::test
