#include "train/band_draw.h"

#include "core/error.h"
#include "core/parallel.h"
#include "train/seed.h"

namespace ddhgs::train {

torch::Tensor draw_bands(int64_t bands, int64_t count, uint64_t seed) {
  core::require(bands >= 1 && count >= 1, "band draw: needs at least one band");
  if (count >= bands) return torch::arange(bands, torch::kInt64);
  torch::Tensor index = torch::empty({count}, torch::kInt64);
  int64_t* out = index.data_ptr<int64_t>();
  for (int64_t j = 0; j < count; ++j) {
    const int64_t lo = j * bands / count, hi = (j + 1) * bands / count;
    out[j] = lo + int64_t(mix_seed(seed, uint64_t(j)) % uint64_t(hi - lo));
  }
  return index;
}

torch::Tensor select_bands(const torch::Tensor& image, const torch::Tensor& index) {
  core::require(image.dim() == 3 && image.scalar_type() == torch::kFloat32,
                "band draw: select_bands needs an [H, W, N] float32 image");
  const torch::Tensor in = image.contiguous();
  const int64_t pixels = in.size(0) * in.size(1), n = in.size(2), count = index.size(0);
  torch::Tensor out = torch::empty({in.size(0), in.size(1), count}, in.options());
  const float* src = in.data_ptr<float>();
  float* dst = out.data_ptr<float>();
  const int64_t* bands = index.data_ptr<int64_t>();
  core::parallel_for(0, pixels, 4096, [&](int64_t begin, int64_t end) {
    for (int64_t p = begin; p < end; ++p)
      for (int64_t j = 0; j < count; ++j) dst[p * count + j] = src[p * n + bands[j]];
  });
  return out;
}

}  // namespace ddhgs::train
