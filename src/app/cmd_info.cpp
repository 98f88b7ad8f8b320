// `ddhgs info DIR`: what a dataset holds and what is wrong with it.
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <optional>

#include "app/registry.h"
#include "core/error.h"
#include "core/log.h"
#include "core/spectral_pca.h"
#include "core/tensor_values.h"
#include "io/rig/rig_capture.h"
#include "io/rig/rig_layout.h"
#include "io/rig/rig_radiometry.h"
#include "io/scene/backdrop.h"
#include "io/scene/scene.h"
#include "io/scene/scene_report.h"

namespace ddhgs::app {
namespace cmd_info {

struct InfoArgs {
  std::string dir;
  int downscale = 1;
  bool rgb = false;
  bool json = false;
};

std::string human_bytes(size_t bytes) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  double v = double(bytes);
  int u = 0;
  while (v >= 1024 && u < 4) {
    v /= 1024;
    ++u;
  }
  char buf[32];
  std::snprintf(buf, sizeof buf, u == 0 ? "%.0f %s" : "%.1f %s", v, units[u]);
  return buf;
}

std::string fixed1(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f", v);
  return buf;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// "training views 14.0 deg from their nearest neighbour (median; 1.7-15.2);
// test views 13.3-14.9 deg from the nearest training view": the gap the
// held-out views must be interpolated across.
std::string spacing_line(const io::ViewSpacing& s) {
  if (s.train_nearest_deg.empty()) return "fewer than 2 training views";
  std::string out = "training views " + fixed1(median(s.train_nearest_deg)) +
                    " deg from their nearest neighbour (median; " +
                    io::degree_range(s.train_nearest_deg) + ")";
  if (!s.test_nearest_deg.empty())
    out += "; test views " + io::degree_range(s.test_nearest_deg) +
           " deg from the nearest training view";
  return out;
}

std::string nm(double v) {
  return core::format_g(v);
}

// The border of the training views, read only when every view's header
// checked out; a view that still fails to decode leaves it unchecked, with
// the reason, rather than stopping info.
struct BorderCheck {
  std::optional<io::BorderScan> scan;
  std::string why_not;
};

BorderCheck border_of(const io::Scene& scene, const io::SceneReport& r) {
  if (!r.errors.empty()) return {std::nullopt, "views fail to load"};
  if (scene.train.empty()) return {std::nullopt, "no training views"};
  try {
    return {io::scan_border(scene, scene.train), ""};
  } catch (const core::Error& e) {
    return {std::nullopt, e.what()};
  }
}

// Principal components of the training views' pixel spectra: the rank a
// subspace colour model needs (model.spectral_rank). Like the border, read only when
// every view's header checked out.
struct SpectraCheck {
  std::optional<core::SpectralPca> pca;
  int views = 0;
  int64_t samples = 0;
  std::string why_not;
  int64_t whitened_rank = 0;  // core::whitened_signal_rank
};

constexpr int kPcaViews = 8;

SpectraCheck spectra_of(const io::Scene& scene, const io::SceneReport& r) {
  if (scene.bands() < 2) return {std::nullopt, 0, 0, "one band"};
  if (!r.errors.empty()) return {std::nullopt, 0, 0, "views fail to load"};
  if (scene.train.empty()) return {std::nullopt, 0, 0, "no training views"};
  if (scene.band_per_view())
    return {std::nullopt, 0, 0, "a band-per-view scene: no view holds whole spectra"};
  try {
    const io::SpectraSample sample = io::sample_spectra(scene, kPcaViews);
    return {core::spectral_pca(sample.spectra), sample.views, sample.spectra.size(0), "",
            core::whitened_signal_rank(sample.spectra, sample.noise_sigma)};
  } catch (const core::Error& e) {
    return {std::nullopt, 0, 0, e.what()};
  }
}

// "signal in 4 of 141 components above the noise floor (99 % of the
// variance in 3, 99.9 % in 115; 8 training views, 81920 pixels)".
std::string spectra_line(const SpectraCheck& c) {
  if (!c.pca) return "not checked (" + c.why_not + ")";
  const core::SpectralPca& p = *c.pca;
  if (p.rank_for(0.999) == 0) return "do not vary";
  return "signal in " + std::to_string(p.signal_rank()) + " of " + std::to_string(p.bands()) +
         " components above the noise floor, " + std::to_string(c.whitened_rank) +
         " with each band's noise whitened (99 % of the variance in " +
         std::to_string(p.rank_for(0.99)) + ", 99.9 % in " + std::to_string(p.rank_for(0.999)) +
         "; " + std::to_string(c.views) + " training views, " + std::to_string(c.samples) +
         " pixels)";
}

std::string backdrop_line(const BorderCheck& b) {
  if (!b.scan) return "not checked (" + b.why_not + ")";
  if (!b.scan->masked) return "none (" + b.scan->why_not + ")";
  const std::string share = std::to_string(int(std::lround(100 * b.scan->share))) + " %";
  return "masked to " + io::describe_colour(b.scan->colour) + " on " + share +
         " of the view borders (the background starts from it; eval also measures the object "
         "alone)";
}

nlohmann::json to_json(const io::Scene& scene, const io::SceneReport& r, const BorderCheck& border,
                       const SpectraCheck& spectra) {
  nlohmann::json j;
  j["root"] = scene.root.string();
  j["layout"] = scene.layout;
  j["views"] = scene.views.size();
  j["train"] = scene.train.size();
  j["test"] = scene.test.size();
  j["width"] = r.width;
  j["height"] = r.height;
  j["mixed_sizes"] = r.mixed_sizes;
  j["downscale"] = scene.options.downscale;
  j["bands"] = scene.bands();
  j["wavelengths_nm"] = scene.wavelengths_nm;
  j["stored_type"] = io::to_string(scene.stored_type);
  j["scale"] = scene.scale;
  j["bytes_per_view"] = scene.view_bytes();
  j["bytes_scene"] = r.scene_bytes;
  j["bytes_per_view_float32"] = scene.view_bytes() / io::bytes_per_sample(scene.stored_type) * 4;
  j["bytes_scene_float32"] = r.scene_bytes_f32;
  j["points"] = r.points;
  j["point_colors"] = r.point_colors;
  j["point_spectra"] = r.point_spectra;
  j["clean_views"] = r.clean_views;
  j["distorted_views"] = r.distorted_views;
  j["fov_deg"] = {r.fov_x_deg, r.fov_y_deg};
  j["train_nearest_view_deg"] = r.spacing.train_nearest_deg;
  j["test_nearest_train_view_deg"] = r.spacing.test_nearest_deg;
  // The border's median colour, the share of the border and of the views on
  // it, its spread, the share of views whose middle it fills; "masked" when training's background
  // starts from it and eval measures the object alone (io/scene/backdrop.h), else why not.
  if (border.scan) {
    const io::BorderScan& b = *border.scan;
    j["border"] = {{"colour", core::to_doubles(b.colour)}, {"share", b.share},
                   {"view_share", b.view_share},           {"spread", b.spread},
                   {"filled_share", b.filled_share},       {"masked", b.masked}};
    if (!b.masked) j["border"]["why_not"] = b.why_not;
  }
  // Share of the variance per principal component of the pixel spectra, and
  // the ranks that keep 99 % and 99.9 % of it.
  if (spectra.pca)
    j["spectral_pca"] = {{"energy", spectra.pca->energy},
                         {"rank_99", spectra.pca->rank_for(0.99)},
                         {"rank_99_9", spectra.pca->rank_for(0.999)},
                         {"signal_rank", spectra.pca->signal_rank()},
                         {"whitened_signal_rank", spectra.whitened_rank},
                         {"views", spectra.views},
                         {"pixels", spectra.samples}};
  if (scene.georef) {
    const io::Georeference& g = *scene.georef;
    const core::Similarity& s = g.scene_to_crs;
    j["georef"] = {{"epsg", g.epsg},
                   {"metres_per_unit", s.scale},
                   {"translation_m", {s.translation.x, s.translation.y, s.translation.z}},
                   {"gps_captures", g.captures},
                   {"gps_rms_m", g.rms_m},
                   {"gps_worst_m", g.worst_m},
                   {"gps_worst_capture", g.worst_capture},
                   {"orientation_from", g.orientation_from}};
  }
  if (scene.rig) {
    j["rig"] = {{"band_cameras", scene.rig->cameras.size()},
                {"reference_camera", scene.rig->reference_camera}};
    if (scene.rig->unit_m > 0) j["rig"]["unit_m"] = scene.rig->unit_m;
  }
  j["notes"] = scene.notes;
  j["warnings"] = scene.warnings;
  j["errors"] = r.errors;
  return j;
}

// "40, 400-700 nm"; RGB images list their three nominal wavelengths in
// band order (R, G, B: descending), which a range would hide.
std::string bands_text(const io::Scene& scene) {
  const auto& w = scene.wavelengths_nm;
  std::string out = std::to_string(scene.bands());
  if (w.empty()) return out;
  if (scene.options.rgb) {
    out += " (the RGB images, at";
    for (size_t i = 0; i < w.size(); ++i) out += (i ? ", " : " ") + nm(w[i]);
    return out + " nm)";
  }
  auto [lo, hi] = std::minmax_element(w.begin(), w.end());
  return out + ", " + nm(*lo) + "-" + nm(*hi) + " nm";
}

// A rig scene's band cameras, the camera whose poses they follow, and its
// unit, which decides whether lever arms and corrections read in cm.
std::string rig_line(const io::TransformsRig& rig) {
  std::string out = std::to_string(rig.cameras.size()) + " band cameras, posed from camera " +
                    std::to_string(rig.reference_camera);
  if (const io::RigCameraInfo* reference = rig.camera(rig.reference_camera))
    if (!reference->band.empty()) out += " (" + reference->band + ")";
  if (rig.unit_m > 0)
    return out + "; " + nm(rig.unit_m) + " m per scene unit (corrections and lever arms in cm)";
  return out + "; scene unit unknown (lever arms in scene units, not cm)";
}

void print_text(const io::Scene& scene, const io::SceneReport& r, const BorderCheck& border,
                const SpectraCheck& spectra) {
  std::ostream& out = std::cout;
  size_t f32_view = scene.view_bytes() / io::bytes_per_sample(scene.stored_type) * 4;
  out << "dataset     " << scene.root.string() << " (" << scene.layout << ")\n"
      << "views       " << scene.views.size() << " (train " << scene.train.size() << ", test "
      << scene.test.size() << ")\n"
      << "resolution  " << r.width << " x " << r.height << " px"
      << (r.mixed_sizes ? " (first view; sizes vary)" : "")
      << (scene.options.downscale > 1 ? " at downscale " + std::to_string(scene.options.downscale)
                                      : "")
      << "\n"
      << "bands       " << bands_text(scene) << "\n"
      << "stored as   " << io::to_string(scene.stored_type) << " (divided by " << nm(scene.scale)
      << ")\n"
      << "memory      " << human_bytes(scene.view_bytes()) << " per view, "
      << human_bytes(r.scene_bytes) << " for the scene as stored; " << human_bytes(f32_view)
      << " / " << human_bytes(r.scene_bytes_f32) << " as float32\n"
      << "points      ";
  if (r.points == 0)
    out << "none (random initialisation)\n";
  else
    out << r.points
        << (r.point_spectra  ? " with spectra"
            : r.point_colors ? " with RGB colours"
                             : " without colours")
        << "\n";
  out << "clean       "
      << (r.clean_views ? std::to_string(r.clean_views) + " views with clean ground truth" : "none")
      << "\n"
      << "cameras     "
      << (r.distorted_views ? std::to_string(r.distorted_views) +
                                  " views with lens distortion, undistorted to pinhole at load"
                            : std::string("pinhole"))
      << ", field of view " << fixed1(r.fov_x_deg) << " x " << fixed1(r.fov_y_deg) << " deg\n"
      << "spacing     " << spacing_line(r.spacing) << "\n"
      << "backdrop    " << backdrop_line(border) << "\n"
      << "spectra     " << spectra_line(spectra) << "\n"
      << "georef      "
      << (scene.georef ? io::describe_georeference(*scene.georef)
                       : std::string("none (no georef.json: not placed on the earth)"))
      << "\n";
  if (scene.rig) out << "rig         " << rig_line(*scene.rig) << "\n";
  for (const auto& note : scene.notes) out << "  note: " << note << "\n";
  if (scene.warnings.empty() && r.errors.empty()) {
    out << "problems    none\n";
    return;
  }
  out << "problems    " << r.errors.size() << " error(s), " << scene.warnings.size()
      << " warning(s)\n";
  for (const auto& e : r.errors) out << "  error: " << e << "\n";
  for (const auto& w : scene.warnings) out << "  warning: " << w << "\n";
}

// A folder of multispectral rig captures (io/rig/rig_capture.h): its band
// cameras, each camera's angle to the rig's reference camera, and its captures.
int describe_rig(const std::string& dir, bool as_json) {
  const std::vector<io::RigCapture> captures = io::read_rig_captures(dir);
  const std::vector<io::RigBandImage>& bands = captures.front().bands;
  // The camera in pixels: focal length and principal point (empty: the file
  // does not say).
  auto pixels_of = [](const io::RigBandImage& b) -> std::optional<core::Intrinsics> {
    try {
      return io::rig_intrinsics(b);
    } catch (const core::Error&) {
      return std::nullopt;
    }
  };
  nlohmann::json cameras = nlohmann::json::array();
  for (const io::RigBandImage& b : bands) {
    const std::optional<core::Intrinsics> k = pixels_of(b);
    nlohmann::json in_pixels = nullptr;
    if (k)
      in_pixels = {{"focal_length_px", k->fx},
                   {"principal_point_px", {k->cx, k->cy}},
                   {"focal_length_units_in_file", b.focal_length_units},
                   {"units_from", b.focal_units_from}};
    cameras.push_back({{"rig_index", b.rig_index},
                       {"band", b.band_name},
                       {"centre_nm", b.centre_nm},
                       {"fwhm_nm", b.fwhm_nm},
                       {"width", b.width},
                       {"height", b.height},
                       {"bits", b.bits},
                       {"focal_length_in_file", b.focal_length_mm},
                       {"intrinsics", in_pixels},
                       {"rig_relatives_deg", b.rig_relatives_deg},
                       {"angle_to_reference_deg", io::rig_relative_angle_deg(b.rig_relatives_deg)},
                       {"radiometry",
                        {{"black_level", b.radiometry.black_level},
                         {"exposure_s", b.radiometry.exposure_s},
                         {"gain", b.radiometry.gain()},
                         {"calibration", b.radiometry.calibration},
                         {"vignetting_centre_px", b.radiometry.vignetting_centre_px},
                         {"vignetting_polynomial", b.radiometry.vignetting_polynomial},
                         {"irradiance", b.radiometry.irradiance},
                         {"irradiance_raw", b.radiometry.irradiance_raw},
                         {"irradiance_tag", b.radiometry.irradiance_tag},
                         {"irradiance_correction", b.radiometry.irradiance_correction}}}});
  }
  // Radiance needs exposure, gain and calibration in every file;
  // reflectance a panel capture or a DLS reading in every file.
  std::string no_radiance, no_dls;
  for (const io::RigCapture& c : captures)
    for (const io::RigBandImage& b : c.bands) {
      if (no_radiance.empty()) try {
          io::require_radiometry(b);
        } catch (const core::Error& e) {
          no_radiance = e.what();
        }
      if (no_dls.empty() && b.radiometry.irradiance <= 0) no_dls = b.file.string();
    }
  const std::string radiance = no_radiance.empty() ? "every band image" : "no: " + no_radiance;
  const std::string reflectance =
      !no_radiance.empty() ? "no (no radiance)"
      : no_dls.empty()     ? "from the DLS in every capture, or a panel capture (--panel)"
                           : "needs a panel capture (--panel): no DLS irradiance in " + no_dls;
  // A folder of one or two captures may be a panel capture: where each
  // band's panel lies (io::locate_panel, as process --panel finds it).
  nlohmann::json panels = nlohmann::json::array();
  std::vector<std::string> panel_lines;
  if (captures.size() < 3 && no_radiance.empty())
    for (const io::RigCapture& c : captures) {
      nlohmann::json per_band = nlohmann::json::array();
      int placed = 0, found = 0;
      int64_t fewest = 0, most = 0;
      std::string label, missing;
      for (const io::RigBandImage& b : c.bands) {
        const std::optional<io::PanelRegion> region =
            io::locate_panel(b, io::band_signal(b, io::read_band_counts(b)));
        if (!region) {
          missing += (missing.empty() ? "" : ", ") + b.band_name;
          per_band.push_back({{"band", b.band_name}, {"region", "none"}});
          continue;
        }
        (region->label.empty() ? found : placed) += 1;
        if (!region->label.empty()) label = region->label;
        fewest = fewest == 0 ? region->pixels : std::min(fewest, region->pixels);
        most = std::max(most, region->pixels);
        per_band.push_back({{"band", b.band_name},
                            {"region", io::panel_region_source(*region)},
                            {"label", region->label},
                            {"pixels", region->pixels}});
      }
      // Named by its files (IMG_0000_*), which a person sees, not its capture id.
      std::string files = c.bands.front().file.stem().string();
      if (const size_t cut = files.rfind('_'); cut != std::string::npos && cut > 0)
        files = files.substr(0, cut) + "_*";
      panels.push_back({{"capture", c.id}, {"files", files}, {"bands", per_band}});
      const int bands_with = placed + found, all = int(c.bands.size());
      std::string line = files + ": ";
      if (bands_with == 0) {
        line += "no panel in any band";
      } else {
        if (placed > 0)
          line += "placed by label " + label + " in " + std::to_string(placed) + " of " +
                  std::to_string(all) + " bands";
        if (found > 0)
          line += std::string(placed > 0 ? ", " : "") + "found in " + std::to_string(found) +
                  " of " + std::to_string(all) + " bands";
        line += " (" + std::to_string(fewest) +
                (most > fewest ? "-" + std::to_string(most) : std::string()) + " px)";
        if (!missing.empty()) line += "; none in " + missing;
      }
      panel_lines.push_back(line);
    }
  if (as_json) {
    nlohmann::json ids = nlohmann::json::array();
    for (const io::RigCapture& c : captures) ids.push_back(c.id);
    std::cout << nlohmann::json{{"dataset", dir},
                                {"layout", "rig captures"},
                                {"captures", ids},
                                {"cameras", cameras},
                                {"radiance", no_radiance.empty()},
                                {"reflectance", reflectance},
                                {"panels", panels}}
                     .dump(2)
              << "\n";
    return 0;
  }
  std::cout << "dataset     " << dir << " (multispectral rig captures, one TIFF per band)\n"
            << "captures    " << captures.size() << " (" << captures.front().id
            << (captures.size() > 1 ? " ... " + captures.back().id : std::string()) << ")\n"
            << "rig         " << bands.size() << " band cameras\n";
  for (const io::RigBandImage& b : bands) {
    char line[320];
    const std::optional<core::Intrinsics> k = pixels_of(b);
    char turn[80] = "no rig rotation in the file (taken as parallel to the others)";
    if (!b.rig_relatives_deg.empty())
      std::snprintf(turn, sizeof turn, "%.3f deg from the reference",
                    io::rig_relative_angle_deg(b.rig_relatives_deg));
    char lens[96] = "focal length unknown";
    if (!k && b.focal_length_mm > 0)
      std::snprintf(lens, sizeof lens, "focal %.2f %s", b.focal_length_mm,
                    b.focal_length_units.c_str());
    if (k)
      std::snprintf(lens, sizeof lens, "focal %.1f px, principal point (%.1f, %.1f) px", k->fx,
                    k->cx, k->cy);
    std::snprintf(line, sizeof line,
                  "  camera %d  %-10s %6.1f nm (FWHM %.1f), %lld x %lld px, %d bits, %s, %s\n",
                  b.rig_index, b.band_name.c_str(), b.centre_nm, b.fwhm_nm, (long long)b.width,
                  (long long)b.height, b.bits, lens, turn);
    std::cout << line;
    const io::RigRadiometry& r = b.radiometry;
    std::snprintf(line, sizeof line,
                  "            black level %.0f, exposure %.3f ms, gain %.2gx, calibration %s, "
                  "vignetting %s, DLS %s\n",
                  r.black_level, r.exposure_s * 1e3, r.gain(),
                  r.calibration.size() == 3 ? "yes" : "none",
                  r.vignetting_polynomial.empty() ? "none" : "yes",
                  r.irradiance > 0 ? (std::to_string(r.irradiance) + " W/m2/nm").c_str() : "none");
    std::cout << line;
    if (r.irradiance > 0 && r.irradiance != r.irradiance_raw) {
      std::snprintf(line, sizeof line, "            DLS as read %.6f W/m2/nm (%s); corrected: %s\n",
                    r.irradiance_raw, r.irradiance_tag.c_str(), r.irradiance_correction.c_str());
      std::cout << line;
    }
  }
  std::cout << "radiance    " << radiance << "\n"
            << "reflectance " << reflectance << "\n";
  for (size_t i = 0; i < panel_lines.size(); ++i)
    std::cout << (i == 0 ? "panel       " : "            ") << panel_lines[i] << "\n";
  if (captures.size() < 3)
    std::cout << "  next: " << captures.size()
              << " capture(s) cannot be posed; a panel capture goes to ddhgs process FLIGHT --rig "
                 "--panel "
              << dir << " --panel-albedo a,b,... with a flight of 3 or more captures\n";
  else
    std::cout << "  next: ddhgs process " << dir
              << " --rig --out SCENE (reflectance, poses) gives a scene to train\n";
  return 0;
}

Action setup(CLI::App& parent) {
  auto args = std::make_shared<InfoArgs>();
  CLI::App* cmd = parent.add_subcommand(
      "info", "Describe a dataset: views, split, bands, memory, points and problems");
  cmd->add_option("dir", args->dir,
                  "Dataset folder (transforms.json or COLMAP layout), or a folder of "
                  "multispectral rig captures (MicaSense TIFFs)")
      ->required();
  cmd->add_option("--downscale", args->downscale, "Describe the views at 1/d resolution")
      ->check(within(1, 4096));
  cmd->add_flag("--rgb", args->rgb, "Describe the RGB images instead of the cubes");
  cmd->add_flag("--json", args->json, "Print one JSON object instead of text");
  return [args] {
    if (io::looks_like_rig_captures(args->dir)) return describe_rig(args->dir, args->json);
    io::LoadOptions options;
    options.downscale = args->downscale;
    options.rgb = args->rgb;
    auto scene = io::load_scene(args->dir, options);
    io::SceneReport report = io::inspect_scene(*scene);
    const BorderCheck border = border_of(*scene, report);
    const SpectraCheck spectra = spectra_of(*scene, report);
    if (args->json)
      std::cout << to_json(*scene, report, border, spectra).dump(2) << "\n";
    else
      print_text(*scene, report, border, spectra);
    // Problems that would stop training make the exit status non-zero.
    return report.errors.empty() ? 0 : 1;
  };
}

Registrar registrar("info", 20, setup);

}  // namespace cmd_info
}  // namespace ddhgs::app
