#include "train/band_draw.h"

#include "core/error.h"
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

}  // namespace ddhgs::train
