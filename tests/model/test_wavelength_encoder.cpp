#include <gtest/gtest.h>
#include <torch/optim/adam.h>

#include "core/error.h"
#include "model/wavelength_encoder.h"

using namespace ddhgs::model;

TEST(WavelengthEncoder, NormalisesOverTheSensorRange) {
  auto x = normalise_wavelengths({400, 550, 1100});
  EXPECT_FLOAT_EQ(x[0].item<float>(), 0.0f);
  EXPECT_NEAR(x[1].item<float>(), 150.0 / 700.0, 1e-7);
  EXPECT_FLOAT_EQ(x[2].item<float>(), 1.0f);
  EXPECT_FLOAT_EQ(normalise_wavelengths({700})[0].item<float>(), 0.5f);
}

TEST(WavelengthEncoder, PositionalEncodingMatchesHandValues) {
  auto x = torch::tensor({0.25f});
  auto e = positional_encoding(x, 2, true);
  ASSERT_EQ(e.sizes(), (std::vector<int64_t>{1, 5}));
  // [x, sin(pi x), cos(pi x), sin(2 pi x), cos(2 pi x)]
  std::vector<float> expected{0.25f, float(std::sin(M_PI / 4)), float(std::cos(M_PI / 4)), 1.0f,
                              0.0f};
  for (int i = 0; i < 5; ++i) EXPECT_NEAR(e[0][i].item<float>(), expected[i], 1e-6) << i;
  EXPECT_EQ(positional_encoding(x, 10, false).size(1), 20);
}

TEST(WavelengthEncoder, StartsAtZeroAndLearns) {
  WavelengthEncoderOptions opts;
  opts.hidden = 16;
  opts.output_scale = 1.0;
  WavelengthEncoder enc(opts);
  auto lambda = normalise_wavelengths({400, 500, 600, 700, 800});
  auto out = enc->forward(lambda);
  ASSERT_EQ(out.sizes(), (std::vector<int64_t>{5, 16}));
  EXPECT_EQ(out.abs().max().item<float>(), 0.0f);

  // Fit a smooth target offset per band; the loss must fall by a large factor.
  auto target = torch::sin(lambda * 3.0).unsqueeze(1).expand({5, 16}) * 0.1;
  torch::optim::Adam adam(enc->parameters(), torch::optim::AdamOptions(1e-2));
  double first = 0, last = 0;
  for (int step = 0; step < 300; ++step) {
    adam.zero_grad();
    auto loss = (enc->forward(lambda) - target).pow(2).mean();
    loss.backward();
    adam.step();
    if (step == 0) first = loss.item<double>();
    last = loss.item<double>();
  }
  EXPECT_LT(last, first * 0.05);
}

TEST(WavelengthEncoder, OutputScaleMultipliesOffsets) {
  WavelengthEncoderOptions a_opts, b_opts;
  a_opts.output_scale = 1.0;
  b_opts.output_scale = 0.01;
  torch::manual_seed(0);
  WavelengthEncoder a(a_opts);
  torch::manual_seed(0);
  WavelengthEncoder b(b_opts);
  {
    torch::NoGradGuard g;
    for (auto* enc : {&a, &b}) {
      auto params = (*enc)->parameters();
      params.back().fill_(0.3f);  // non-zero last bias so outputs differ from 0
    }
  }
  auto lambda = normalise_wavelengths({400, 700, 1000});
  EXPECT_TRUE(torch::allclose(b->forward(lambda), a->forward(lambda) * 0.01, 1e-6, 1e-8));
}

TEST(WavelengthEncoder, RejectsBadOptions) {
  WavelengthEncoderOptions opts;
  opts.layers = 0;
  EXPECT_THROW(WavelengthEncoder{opts}, ddhgs::core::Error);
  EXPECT_THROW(normalise_wavelengths({}), ddhgs::core::Error);
}
