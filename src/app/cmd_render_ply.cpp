// `ddhgs render-ply SCENE.ply --camera CAM.json --out IMAGE.npy`: renders an
// N-band Gaussian PLY from one camera, so the renderer can be checked
// against other tools on the same file.
#include <chrono>

#include "app/number_list.h"
#include "app/registry.h"
#include "core/colour.h"
#include "core/error.h"
#include "core/log.h"
#include "io/cube/cube.h"
#include "io/files/output_file.h"
#include "io/image/image.h"
#include "io/ply/ply.h"
#include "io/transforms/camera_json.h"
#include "model/gaussians.h"
#include "render/rasterize.h"

namespace ddhgs::app {
namespace cmd_render_ply {
namespace fs = std::filesystem;

struct RenderPlyArgs {
  std::string ply, camera, out, preview;
  std::string background = "0";
  int sh_degree = -1;  // -1: the file's degree
};

// "--background 0.2" (every band) or one comma-separated value per band.
torch::Tensor parse_background(const std::string& text, int64_t bands) {
  const std::vector<double> parsed = parse_number_list(text, "--background");
  const std::vector<float> values(parsed.begin(), parsed.end());
  if (values.size() == 1) return torch::full({bands}, values[0]);
  if (int64_t(values.size()) != bands)
    throw core::Error("--background: " + std::to_string(values.size()) +
                      " values for a scene with " + std::to_string(bands) +
                      " bands (give one value, or one per band)");
  return torch::tensor(values);
}

// Pseudo-RGB through the CIE observer when the bands reach the visible
// range; otherwise three bands spread over the spectrum (long wavelengths
// as red), scaled so the brightest of them is white.
torch::Tensor preview_picture(const torch::Tensor& image,  // [H, W, N]
                              const std::vector<double>& wavelengths_nm) {
  const int64_t N = image.size(2);
  bool visible = N == 3 && wavelengths_nm.empty();
  for (double w : wavelengths_nm) visible |= w > core::kCmfMinNm && w < core::kCmfMaxNm;
  bool increasing = true;  // pseudo_rgb needs a strictly increasing grid
  for (size_t i = 1; i < wavelengths_nm.size(); ++i)
    increasing &= wavelengths_nm[i] > wavelengths_nm[i - 1];
  if (visible && increasing) return core::pseudo_rgb(image, wavelengths_nm);
  auto indices = torch::tensor({(N - 1) * 3 / 4, (N - 1) / 2, (N - 1) / 4});
  auto rgb = image.index_select(2, indices);
  return (rgb / std::max(rgb.max().item<float>(), 1e-6f)).clamp(0, 1);
}

// Before any work: outputs that overwrite no input (said as such before a
// wrong extension), of the right kind.
void check_outputs(const RenderPlyArgs& args) {
  io::require_distinct(args.out, "--out",
                       {{"the input PLY", args.ply}, {"the --camera file", args.camera}});
  io::require_extension(args.out, "--out", {".npy"});
  if (args.preview.empty()) return;
  io::require_distinct(args.preview, "--preview",
                       {{"the input PLY", args.ply},
                        {"the --camera file", args.camera},
                        {"the --out file", args.out}});
  io::require_extension(args.preview, "--preview", {".png"});
}

int run(const RenderPlyArgs& args) {
  const auto start = std::chrono::steady_clock::now();
  check_outputs(args);
  io::GaussianPly scene = io::read_gaussian_ply(args.ply);
  const core::Camera camera = io::read_camera_json(args.camera);
  const int file_degree = scene.sh_degree();
  const int degree = args.sh_degree < 0 ? file_degree : args.sh_degree;
  if (degree > file_degree)
    throw core::Error("--sh-degree " + std::to_string(degree) + ": " + args.ply +
                      " only has coefficients up to degree " + std::to_string(file_degree));
  const int64_t N = scene.bands();
  const torch::Tensor background = parse_background(args.background, N);

  torch::NoGradGuard no_grad;
  model::Gaussians gaussians = model::from_ply(scene);
  gaussians.active_sh_degree = degree;
  const auto output = model::render_gaussians(gaussians, camera, background);
  // The preview is made before anything is written, so a failure leaves no files.
  torch::Tensor preview;
  if (!args.preview.empty()) preview = preview_picture(output.image, scene.wavelengths_nm);
  io::write_npy(args.out, output.image.contiguous());
  if (preview.defined()) io::write_png(args.preview, preview);

  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  core::log_info("rendered " + std::to_string(scene.means.size(0)) + " Gaussians, " +
                 std::to_string(N) + " bands, SH degree " + std::to_string(degree) + " at " +
                 std::to_string(camera.intrinsics.width) + "x" +
                 std::to_string(camera.intrinsics.height) + " to " + args.out + " in " +
                 core::format_duration(seconds));
  return 0;
}

Action setup(CLI::App& parent) {
  auto args = std::make_shared<RenderPlyArgs>();
  CLI::App* cmd = parent.add_subcommand(
      "render-ply", "Render an N-band Gaussian PLY from a camera given as JSON to a .npy cube");
  cmd->add_option("ply", args->ply, "Gaussian PLY (x y z f_dc_* f_rest_* opacity scale_* rot_*)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--camera", args->camera,
                  "Camera JSON: width, height, fx, fy, cx, cy (pixels), world_to_camera "
                  "(4x4 row-major, OpenCV axes)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--out", args->out, "Output cube, float32 [H, W, N] .npy")->required();
  cmd->add_option("--background", args->background,
                  "Background reflectance: one value, or one per band separated by commas")
      ->capture_default_str();
  cmd->add_option("--preview", args->preview, "Also write a pseudo-RGB PNG preview");
  cmd->add_option("--sh-degree", args->sh_degree,
                  "Evaluate SH up to this degree (default: the file's degree)")
      ->check(within(0, 3));
  return [args] { return run(*args); };
}

const Registrar registrar("render-ply", 65, setup);

}  // namespace cmd_render_ply
}  // namespace ddhgs::app
