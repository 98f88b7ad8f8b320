// Scene: lazy, cached access to the views of a loaded dataset, and the split.
//
// Views are kept in their stored sample type (a BaySpec scene is 20 GB as
// uint8, 80 GB as float). When a view is area-averaged or bands are binned,
// the averages are rounded back to the stored integer type: the rounding
// error (half a quantisation step) is no larger than the file's own.
#include <algorithm>
#include <cmath>

#include "core/colour.h"
#include "core/error.h"
#include "core/log.h"
#include "core/parallel.h"
#include "core/text.h"
#include "io/scene/scene.h"

namespace ddhgs::io {
namespace fs = std::filesystem;

namespace {

// Float samples in file units -> the stored type, rounding and clamping integers.
torch::Tensor to_stored(const torch::Tensor& values, SampleType type) {
  switch (type) {
    case SampleType::F16:
      return values.to(torch::kHalf);
    case SampleType::F32:
      return values.to(torch::kFloat);
    case SampleType::F64:
      return values.to(torch::kDouble);
    case SampleType::U8:
      return values.round().clamp(0, 255).to(torch::kUInt8);
    case SampleType::U16:
      // LibTorch has no uint16: keep the 16 bits in an int16 (see cube.h).
      return values.round().clamp(0, 65535).to(torch::kInt32).to(torch::kInt16);
    case SampleType::I16:
      return values.round().clamp(-32768, 32767).to(torch::kInt16);
    case SampleType::I32:
      return values.round().to(torch::kInt32);
  }
  return values;
}

bool is_identity(const std::vector<int>& index, int64_t bands) {
  if (int64_t(index.size()) != bands) return false;
  for (size_t i = 0; i < index.size(); ++i)
    if (index[i] != int(i)) return false;
  return true;
}

}  // namespace

std::vector<double> rgb_wavelengths_nm() {
  return core::rgb_channel_wavelengths_nm();
}

void hypernerf_split(int n, std::vector<int>& train, std::vector<int>& test) {
  train.clear();
  test.clear();
  if (n <= 0) return;
  // Same double arithmetic as math.ceil(n * 0.9) and np.linspace(...).astype(int).
  int k = int(std::ceil(n * 0.9));
  std::vector<bool> is_train(size_t(n), false);
  double step = k > 1 ? double(n - 1) / double(k - 1) : 0;
  for (int i = 0; i < k; ++i) {
    double v = (i == k - 1 && k > 1) ? double(n - 1) : double(i) * step;
    is_train[size_t(std::floor(v))] = true;
  }
  for (int i = 0; i < n; ++i) (is_train[size_t(i)] ? train : test).push_back(i);
}

void require_bands(const fs::path& path, int64_t bands, int64_t expected) {
  if (bands != expected)
    throw core::Error(path, "has " + std::to_string(bands) + " bands, expected " +
                                std::to_string(expected) + " like the scene's other views");
}

void require_named_bands(const fs::path& path, int64_t bands, int64_t named) {
  if (bands != named)
    throw core::Error(path, "has " + std::to_string(bands) + " bands, but its frame names " +
                                std::to_string(named) + " (\"bands\" in transforms.json)");
}

int area_factor(const fs::path& path, int64_t height, int64_t width, const core::Intrinsics& target,
                int downscale) {
  if (height == target.height && width == target.width) return 1;
  if (downscale > 1 && height / downscale == target.height && width / downscale == target.width)
    return downscale;
  throw core::Error(path, "is " + std::to_string(width) + "x" + std::to_string(height) +
                              " pixels, but its camera expects " + std::to_string(target.width) +
                              "x" + std::to_string(target.height) +
                              (downscale > 1 ? " (or " + std::to_string(downscale) +
                                                   " times that, to be area-averaged)"
                                             : ""));
}

void log_scene_messages(const Scene& scene, size_t shown) {
  for (const auto& note : scene.notes) core::log_info(note);
  for (size_t i = 0; i < scene.warnings.size() && i < shown; ++i) core::log_warn(scene.warnings[i]);
  if (scene.warnings.size() > shown)
    core::log_warn("... and " + std::to_string(scene.warnings.size() - shown) +
                   " more warnings (ddhgs info lists them all)");
}

bool Scene::has_clean() const {
  return std::any_of(views.begin(), views.end(),
                     [](const View& v) { return !v.clean_path.empty(); });
}

size_t Scene::view_bytes() const {
  size_t most = 0;
  for (const auto& v : views)
    most = std::max(most, size_t(v.camera.intrinsics.width) * size_t(v.camera.intrinsics.height));
  return most * size_t(bands()) * bytes_per_sample(stored_type);
}

bool Scene::band_per_view() const {
  return std::any_of(views.begin(), views.end(), [](const View& v) { return !v.bands.empty(); });
}

torch::Tensor Scene::view_bands(int view) const {
  core::require(view >= 0 && view < int(views.size()), root,
                "view index " + std::to_string(view) + " out of range");
  const std::vector<int>& b = views[size_t(view)].bands;
  if (b.empty()) return {};
  return torch::tensor(std::vector<int64_t>(b.begin(), b.end()), torch::kInt64);
}

torch::Tensor Scene::view_slice(int view, const torch::Tensor& image) const {
  const torch::Tensor index = view_bands(view);
  return index.defined() ? image.index_select(image.dim() - 1, index) : image;
}

Cube Scene::load_view(const fs::path& path, const View& view) const {
  const core::Intrinsics& target = view.camera.intrinsics;
  Cube cube = read_cube(path, CubeReadOptions{options.layout});
  const bool subset = !view.file_bands.empty();
  if (subset)
    require_named_bands(path, cube.bands(), view.file_band_count);
  else
    require_bands(path, cube.bands(), source_bands);
  int64_t h = cube.height(), w = cube.width();
  int d = area_factor(path, h, w, target, options.downscale);
  bool reduce = d > 1;

  torch::Tensor data = cube.data;
  if (subset) {
    if (!is_identity(view.file_bands, view.file_band_count))
      data = data.index_select(
          2, torch::tensor(std::vector<int64_t>(view.file_bands.begin(), view.file_bands.end())));
  } else if (!is_identity(band_index, source_bands))
    data = data.index_select(
        2, torch::tensor(std::vector<int64_t>(band_index.begin(), band_index.end())));
  int bin = std::max(options.bin, 1);
  if (bin > 1 || reduce || cube.ignore_value) {
    // Average in file units; ignored samples count as 0, as cube_to_float maps them.
    Cube selected{data, cube.type, {}, cube.ignore_value, {}};
    torch::Tensor values = cube_to_float(selected, 1.0);
    int64_t kept = values.size(2);
    if (bin > 1) values = values.reshape({h, w, kept / bin, bin}).mean(3);
    if (reduce) {
      int64_t th = target.height, tw = target.width;
      values = values.slice(0, 0, th * d)
                   .slice(1, 0, tw * d)
                   .reshape({th, d, tw, d, values.size(2)})
                   .mean({1, 3});
    }
    data = to_stored(values, cube.type);
  }
  if (view.undistortion) data = view.undistortion->apply(data, cube.type, path.string());
  Cube out;
  out.data = data.contiguous();
  out.type = cube.type;
  out.scale_factor = cube.scale_factor;
  return out;
}

bool Scene::direct_view(const fs::path& path, const View& view) const {
  const std::string key = path.string();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = direct_.find(key);
    if (it != direct_.end()) return it->second;
  }
  bool direct = core::lower(path.extension().string()) == ".npy" && !view.undistortion &&
                view.file_bands.empty() && std::max(options.bin, 1) == 1 &&
                is_identity(band_index, source_bands);
  if (direct) {
    try {
      const CubeInfo info = probe_cube(path, CubeReadOptions{options.layout});
      direct = info.height == view.camera.intrinsics.height &&
               info.width == view.camera.intrinsics.width && info.bands == source_bands;
    } catch (const core::Error&) {
      direct = false;  // load_view reads it and names the problem
    }
  }
  std::lock_guard<std::mutex> lock(mutex_);
  direct_.emplace(key, direct);
  return direct;
}

Cube Scene::cached_view(const fs::path& path, const View& view) const {
  std::string key = path.string();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = cache_.find(key);
    if (it != cache_.end()) {
      lru_.splice(lru_.begin(), lru_, std::find(lru_.begin(), lru_.end(), key));
      return it->second;
    }
  }
  // Decoding runs unlocked so threads load different views in parallel; a
  // view loaded twice at once is stored once.
  Cube cube = load_view(path, view);
  size_t budget = options.cache_mb * (size_t(1) << 20);
  std::lock_guard<std::mutex> lock(mutex_);
  if (cube.bytes() > budget || cache_.count(key)) return cube;
  while (cached_bytes_ + cube.bytes() > budget && !lru_.empty()) {
    auto victim = cache_.find(lru_.back());
    cached_bytes_ -= victim->second.bytes();
    cache_.erase(victim);
    lru_.pop_back();
  }
  cache_.emplace(key, cube);
  lru_.push_front(key);
  cached_bytes_ += cube.bytes();
  return cube;
}

namespace {

// The samples of data [H, W, B] (any sample type, any row and pixel
// strides: a window of a cached view) at bands, copied bit for bit.
template <typename Bits>
torch::Tensor gather_bands(const torch::Tensor& data, const torch::Tensor& bands) {
  const torch::Tensor in = data.stride(2) == 1 ? data : data.contiguous();
  const int64_t h = in.size(0), w = in.size(1), count = bands.size(0);
  const int64_t row_stride = in.stride(0), pixel_stride = in.stride(1);
  torch::Tensor out = torch::empty({h, w, count}, in.options());
  const auto* src = static_cast<const Bits*>(in.data_ptr());
  auto* dst = static_cast<Bits*>(out.data_ptr());
  const int64_t* index = bands.data_ptr<int64_t>();
  core::parallel_for(0, h * w, 4096, [&](int64_t begin, int64_t end) {
    for (int64_t p = begin; p < end; ++p) {
      const Bits* pixel = src + (p / w) * row_stride + (p % w) * pixel_stride;
      for (int64_t j = 0; j < count; ++j) dst[p * count + j] = pixel[index[j]];
    }
  });
  return out;
}

}  // namespace

torch::Tensor Scene::image(int view, const ImageWindow& window) const {
  core::require(view >= 0 && view < int(views.size()), root,
                "view index " + std::to_string(view) + " out of range");
  const View& v = views[size_t(view)];
  Cube cube;
  int64_t first_row = 0;  // the view's row that is cube's row 0
  if (direct_view(v.data_path, v)) {
    // The file is the view as it is: only the window's rows are read.
    const int64_t height = v.camera.intrinsics.height;
    const int64_t y1 = window.y1 > 0 ? window.y1 : height;
    core::require(window.y0 >= 0 && window.y0 < y1 && y1 <= height, v.data_path,
                  "image window lies outside the view");
    cube = read_cube_rows(v.data_path, window.y0, y1, CubeReadOptions{options.layout});
    first_row = window.y0;
  } else {
    cube = cached_view(v.data_path, v);
  }
  const int64_t x1 = window.x1 > 0 ? window.x1 : cube.width();
  const int64_t y1 = window.y1 > 0 ? window.y1 : first_row + cube.height();
  core::require(window.x0 >= 0 && window.y0 >= first_row && window.x0 < x1 && window.y0 < y1 &&
                    x1 <= cube.width() && y1 <= first_row + cube.height(),
                v.data_path, "image window lies outside the view");
  torch::Tensor data =
      cube.data.slice(0, window.y0 - first_row, y1 - first_row).slice(1, window.x0, x1);
  if (window.bands.defined()) {
    const torch::Tensor& bands = window.bands;
    const bool valid = bands.scalar_type() == torch::kInt64 && bands.dim() == 1 &&
                       (bands.numel() == 0 || (bands.min().item<int64_t>() >= 0 &&
                                               bands.max().item<int64_t>() < cube.bands()));
    core::require(valid, v.data_path, "image window bands out of range");
    switch (cube.data.element_size()) {
      case 1:
        data = gather_bands<uint8_t>(data, bands);
        break;
      case 2:
        data = gather_bands<uint16_t>(data, bands);
        break;
      case 4:
        data = gather_bands<uint32_t>(data, bands);
        break;
      default:
        data = gather_bands<uint64_t>(data, bands);
        break;
    }
  }
  // The cached tensor stays whole: this copy of the cube holds a window of
  // it, whose rows cube_to_float converts without copying them first.
  cube.data = data;
  return cube_to_float(cube, cube.type == stored_type ? scale : 0);
}

torch::Tensor Scene::image(int view) const {
  return image(view, ImageWindow{});
}

torch::Tensor Scene::clean_image(int view) const {
  core::require(view >= 0 && view < int(views.size()), root,
                "view index " + std::to_string(view) + " out of range");
  const View& v = views[size_t(view)];
  if (v.clean_path.empty()) return {};
  Cube cube =
      direct_view(v.clean_path, v) ? load_view(v.clean_path, v) : cached_view(v.clean_path, v);
  // A clean cube stored in another type (e.g. float beside uint8 noisy
  // cubes) is scaled by its own type's default.
  return cube_to_float(cube, cube.type == stored_type ? scale : 0);
}

double scene_extent(const Scene& scene, const std::vector<int>& views) {
  core::require(!views.empty(), scene.root, "no training views");
  core::Vec3 mean;
  for (int v : views) mean = mean + scene.views[v].camera.center() * (1.0 / double(views.size()));
  double radius = 0;
  for (int v : views) radius = std::max(radius, (scene.views[v].camera.center() - mean).norm());
  // A single camera (or coincident ones) has no spread; fall back to unit scale.
  return radius > 0 ? 1.1 * radius : 1.0;
}

}  // namespace ddhgs::io
