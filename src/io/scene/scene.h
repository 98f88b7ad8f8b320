// A scene on disk, loaded lazily: cameras, views, wavelengths, points, split.
//
// Layouts (detected from what is on disk):
//  - transforms.json (nerfstudio / Hyper-NeRF), cubes from hyperspectral_file_path
//  - COLMAP model (sparse/0 or colmap/sparse/0, .bin or .txt) with a folder of
//    cubes matched to the images by file stem
//  - either layout with only RGB images: a 3-band scene
// Clean ground truth (synthetic scenes): a file of the same name under clean/
// in the dataset root, e.g. hyperspectral/r_003.npy -> clean/r_003.npy.
#pragma once
#include "core/tensor.h"

#include <cstddef>
#include <filesystem>
#include <list>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "core/camera.h"
#include "io/cube/cube.h"
#include "io/geo/georef.h"
#include "io/ply/ply.h"
#include "io/rig/rig_layout.h"
#include "io/undistort/undistort.h"

namespace ddhgs::io {

struct LoadOptions {
  int downscale = 1;       // area averaging; uses images_<d>/ folders when present
  bool rgb = false;        // load the RGB file_path images as a 3-band scene
  double band_min_nm = 0;  // keep bands with wavelength in [min, max]
  double band_max_nm = 1e9;
  int bin = 1;             // average groups of this many adjacent bands
  int band_step = 1;       // then keep every band_step-th (held-out bands: ddhgs eval)
  size_t cache_mb = 4096;  // memory budget for decoded views (not for direct .npy views)
  BandLayout layout = BandLayout::Auto;
  std::optional<double> scale;  // overrides the dataset's integer scale
};

struct View {
  std::string name;                  // file stem
  core::Camera camera;               // pinhole, at the loaded (downscaled) resolution
  std::filesystem::path data_path;   // cube, or image for RGB scenes
  std::filesystem::path clean_path;  // empty when there is no clean ground truth
  // A camera with lens distortion: its views are undistorted to
  // camera.intrinsics as they are decoded. Null for a pinhole camera.
  std::shared_ptr<const Undistortion> undistortion;
  // A view of a band-per-view scene (one camera per band, as on a
  // multispectral rig) holds only some of the scene's bands: their indices,
  // ascending. Empty: every band. Scene::image returns just these.
  std::vector<int> bands;
  // Internal (load_scene): the file's band of each entry of `bands`, and
  // how many bands the file holds.
  std::vector<int> file_bands;
  int64_t file_band_count = 0;
  // The rig camera (RigCameraIndex) that took the view, one of Scene::rig's
  // cameras; -1: none.
  int rig_camera = -1;
};

// A part of a view: pixels [x0, x1) x [y0, y1) (x1 or y1 0: to the view's
// edge) and the bands at the int64 indices `bands` into image()'s bands
// (undefined: all, in order).
struct ImageWindow {
  int64_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  torch::Tensor bands;
};

class Scene {
 public:
  std::filesystem::path root;
  std::string layout;  // "transforms.json", "colmap"
  std::vector<View> views;
  std::vector<int> train, test;        // indices into views; disjoint
  std::vector<double> wavelengths_nm;  // one per loaded band
  PointCloud points;                   // xyz undefined when the dataset has none
  // A rig scene's band cameras (transforms.json "rig"); nullopt otherwise.
  std::optional<TransformsRig> rig;
  // The scene's place in a projected CRS (georef.json); nullopt when it has none.
  std::optional<Georeference> georef;
  SampleType stored_type = SampleType::F32;
  double scale = 1;                   // divisor applied to stored samples
  std::vector<std::string> warnings;  // problems found while loading
  std::vector<std::string> notes;     // choices made while loading, worth one info line each

  int64_t bands() const { return int64_t(wavelengths_nm.size()); }
  // True when some view holds only some of the bands (View::bands).
  bool band_per_view() const;
  // The scene bands view v holds, as an int64 index tensor into the bands of
  // a render; undefined when it holds every band.
  torch::Tensor view_bands(int view) const;
  // A render or an [H, W, N] image narrowed to view v's bands, as image()
  // returns them (unchanged when the view holds every band).
  torch::Tensor view_slice(int view, const torch::Tensor& image) const;
  bool has_clean() const;
  // float32 [H, W, N] in [0, 1] at the loaded resolution and bands; for a
  // view that holds some bands, [H, W, its band count].
  torch::Tensor image(int view) const;
  // image(view) narrowed to a window, equal to narrowing image(view) (the
  // conversion is per sample), but converting only the window's samples.
  torch::Tensor image(int view, const ImageWindow& window) const;
  // Clean ground truth, same shape; undefined tensor when there is none.
  torch::Tensor clean_image(int view) const;
  // Bytes one view occupies in the cache (stored type, loaded size).
  size_t view_bytes() const;

  // Internal: set by load_scene.
  LoadOptions options;
  std::vector<int> band_index;  // source band of each loaded band before binning
  int64_t source_bands = 0;     // bands of every cube file before selection

 private:
  // The cube at path (view's data or clean file), reduced to the view's size
  // (area averaging when the file is at full resolution), band-selected,
  // binned and undistorted, in its stored type.
  Cube load_view(const std::filesystem::path& path, const View& view) const;
  // True when the file at path is the view as load_view returns it (a .npy
  // at the view's size, every band in order, no undistortion). Such views
  // are read from the file on every use, only the rows asked for, and never
  // cached: the system's page cache holds the file, memory the system can
  // reclaim, where a copy in the cache would hold it for the whole run.
  bool direct_view(const std::filesystem::path& path, const View& view) const;
  // Cached load_view; evicts least recently used entries beyond cache_mb.
  Cube cached_view(const std::filesystem::path& path, const View& view) const;
  mutable std::mutex mutex_;
  mutable std::list<std::string> lru_;  // most recently used first
  mutable std::unordered_map<std::string, Cube> cache_;
  mutable size_t cached_bytes_ = 0;
  mutable std::unordered_map<std::string, bool> direct_;  // direct_view, by path
};

// Detects the layout and reads metadata (not the cubes). Throws core::Error on
// a malformed dataset; missing frames are skipped with a warning. Prints
// nothing: warnings and notes are collected in the scene (log_scene_messages).
std::unique_ptr<Scene> load_scene(const std::filesystem::path& dir,
                                  const LoadOptions& options = {});

// The one place a loaded scene's notes (info) and warnings are printed, each
// on its own line; beyond `shown` warnings, one line says how many more
// `ddhgs info` lists.
void log_scene_messages(const Scene& scene, size_t shown = 5);

// The Hyper-NeRF rule: train = floor(linspace(0, n-1, ceil(0.9 n))), test = rest.
// Computed in double exactly as numpy/nerfstudio do, so indices match theirs.
void hypernerf_split(int n, std::vector<int>& train, std::vector<int>& test);

// Area-averaging factor that brings a cube of height x width pixels to the
// size of target: 1 when it already has it (e.g. from an images_<d>/ folder),
// downscale when it is at full resolution; otherwise core::Error naming path.
int area_factor(const std::filesystem::path& path, int64_t height, int64_t width,
                const core::Intrinsics& target, int downscale);

// core::Error naming path when a cube's band count differs from the scene's.
void require_bands(const std::filesystem::path& path, int64_t bands, int64_t expected);
// The same for a file whose frame names its bands (View::bands).
void require_named_bands(const std::filesystem::path& path, int64_t bands, int64_t named);

// Wavelengths (nm) given to the three bands of an RGB scene.
std::vector<double> rgb_wavelengths_nm();

// 3DGS's scene extent: 1.1 x the largest distance of a camera centre from
// their mean (scene units). Scales position learning rates and densification.
// (For a narrow field of view it is many times the object's size; it is kept
// because in pixels at the object it is what 3DGS uses: scaling it down to
// the object's size cost 2.9 dB on Basil, docs/benchmarks.md.) A block of a
// flight trains with its flight's (io/blocks/block_grid.h: BlockContext).
double scene_extent(const Scene& scene, const std::vector<int>& views);

}  // namespace ddhgs::io
