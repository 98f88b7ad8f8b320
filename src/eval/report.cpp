#include "eval/report.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "core/colour.h"
#include "core/error.h"
#include "core/log.h"
#include "eval/evaluate.h"
#include "eval/metrics.h"
#include "eval/orthomosaic.h"
#include "eval/report_assets.h"
#include "eval/report_splats.h"
#include "eval/report_views.h"
#include "eval/vegetation_index.h"
#include "io/cube/cube.h"
#include "io/files/atomic_file.h"
#include "io/files/output_folder.h"
#include "io/image/image.h"

namespace ddhgs::eval {
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

// The placeholder in web/report/index.html where the viewer's data scripts go.
constexpr const char* kViewerScriptsMarker = "<!-- viewer data -->";

// Metrics of the report's views against one kind of ground truth.
struct TruthMetrics {
  std::string key;    // "views" or "clean"
  std::string title;  // for tables and legends
  std::vector<ImageMetrics> per_view;

  json row(const std::string& label) const {
    ImageMetrics m = mean_metrics(per_view);
    return {{"label", label},
            {"psnr", m.psnr_db},
            {"ssim", m.ssim},
            {"sam", m.sam_rad},
            {"rmse", m.rmse}};
  }
  std::vector<double> mean_band_psnr() const { return mean_metrics(per_view).band_psnr_db; }
  std::vector<double> mean_band_rmse() const { return mean_metrics(per_view).band_rmse; }
  std::vector<double> sam_per_view() const {
    std::vector<double> out;
    for (const auto& m : per_view) out.push_back(m.sam_rad);
    return out;
  }
};

// Shortest exact-enough text of a number, e.g. 0.1 or 1082.5.
std::string number(double value) {
  return core::format_g(value);
}

// File-name-safe form of a view's stem.
std::string safe_name(const std::string& name) {
  std::string out = name;
  for (char& c : out)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_') c = '_';
  return out;
}

json null_or(const json& record, const char* key) {
  return record.contains(key) ? record.at(key) : json();
}

json training_curves(const std::vector<json>& log) {
  json curves = json::object();
  for (const char* key : {"iter", "seconds", "loss", "train_psnr", "num_gaussians"}) {
    curves[key] = json::array();
    for (const json& record : log)
      if (record.contains("iter")) curves[key].push_back(null_or(record, key));
  }
  // Test-view PSNR against training time (output.test_every), its own points.
  json test = {
      {"minutes", json::array()}, {"test_psnr", json::array()}, {"test_psnr_clean", json::array()}};
  for (const json& record : log) {
    if (!record.contains("test_psnr") || !record.contains("seconds")) continue;
    test["minutes"].push_back(record.at("seconds").get<double>() / 60);
    test["test_psnr"].push_back(record.at("test_psnr"));
    test["test_psnr_clean"].push_back(null_or(record, "test_psnr_clean"));
  }
  curves["test"] = test;
  return curves;
}

json data_summary(const io::Scene& scene, const model::Gaussians& gaussians) {
  const core::Intrinsics& k = scene.views.front().camera.intrinsics;
  json s = {{"dataset", fs::absolute(scene.root).string()},
            {"layout", scene.layout},
            {"views", scene.views.size()},
            {"train views", scene.train.size()},
            {"test views", scene.test.size()},
            {"resolution px", std::to_string(k.width) + " x " + std::to_string(k.height)},
            {"bands", scene.bands()},
            {"stored sample type", io::to_string(scene.stored_type)},
            {"clean ground truth", scene.has_clean() ? "yes (synthetic scene)" : "no"},
            {"sparse points", scene.points.xyz.defined() ? scene.points.xyz.size(0) : 0},
            {"Gaussians", gaussians.size()}};
  if (!scene.wavelengths_nm.empty()) {
    s["wavelengths nm"] =
        number(scene.wavelengths_nm.front()) + " - " + number(scene.wavelengths_nm.back());
  }
  return s;
}

// Rows from eval/metrics.json beyond what the report measures itself, such as
// the object of a masked capture, or the denoiser's output once `ddhgs eval`
// writes it.
void add_eval_rows(const json& eval_metrics, json& rows) {
  if (!eval_metrics.is_object()) return;
  for (const auto& [key, value] : eval_metrics.items()) {
    if (key == "clean" || !value.is_object() || !value.contains("psnr") ||
        !value["psnr"].is_number())
      continue;
    if (key == "object") {
      rows.push_back({{"label", "object: the pixels unlike the backdrop (from eval/metrics.json)"},
                      {"psnr", value["psnr"]},
                      {"ssim", nullptr},
                      {"sam", null_or(value, "sam")},
                      {"rmse", nullptr}});
      if (value.contains("interior_psnr"))
        rows.push_back({{"label", "object less its 1-pixel outline (from eval/metrics.json)"},
                        {"psnr", value["interior_psnr"]},
                        {"ssim", nullptr},
                        {"sam", null_or(value, "interior_sam")},
                        {"rmse", nullptr}});
      continue;
    }
    const std::string label = key == "aligned" ? "render from poses aligned to the views" : key;
    rows.push_back({{"label", label + " (from eval/metrics.json)"},
                    {"psnr", null_or(value, "psnr")},
                    {"ssim", null_or(value, "ssim")},
                    {"sam", null_or(value, "sam")},
                    {"rmse", null_or(value, "rmse")}});
  }
}

std::string metrics_note(const RunRecords& records, size_t views, const std::string& split) {
  std::ostringstream note;
  note << "Means over " << views << " " << split
       << " views, computed as `ddhgs eval` does; PSNR per view then averaged (capped at "
       << kMaxPsnrDb << " dB), SSIM 11x11 Gaussian window, SAM in radians. ";
  const json& e = records.eval_metrics;
  if (e.is_object() && e.contains("fps"))
    note << "Render speed from eval/metrics.json: " << e["fps"].get<double>() << " FPS. ";
  bool denoised = false;
  if (e.is_object())
    for (const auto& item : e.items()) denoised |= item.key().find("denois") != std::string::npos;
  if (!denoised) note << "No denoised output in this run: rows are the raw render.";
  return note.str();
}

void write_viewer_script(const fs::path& path, const std::string& name,
                         const std::vector<std::pair<std::string, torch::Tensor>>& cubes,
                         int max_px, json& meta) {
  json uris;
  for (const auto& [key, cube] : cubes) {
    BandAtlas atlas = band_atlas(cube, max_px);
    uris[key] = png_data_uri(atlas.pixels, path.string() + "." + key + ".png");
    meta = {{"name", name},
            {"width", atlas.width},
            {"height", atlas.height},
            {"cols", atlas.cols},
            {"rows", atlas.rows}};
  }
  io::write_file_atomically(path,
                            "window.DDHGS_VIEWER_DATA = window.DDHGS_VIEWER_DATA || {};\n"
                            "window.DDHGS_VIEWER_DATA[" +
                                json(name).dump() + "] = " + uris.dump() + ";\n");
}

// An existing --out folder is replaced only when it is an earlier report, so
// a mistyped path cannot wipe unrelated files.
}  // namespace

std::vector<json> read_metrics_log(const fs::path& path) {
  std::vector<json> records;
  if (!fs::exists(path)) return records;
  std::istringstream lines(io::read_file(path));
  int number = 0;
  for (std::string line; std::getline(lines, line);) {
    ++number;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    try {
      records.push_back(json::parse(line));
    } catch (const json::exception&) {
      throw core::Error(path, "line " + std::to_string(number) + " is not a JSON object");
    }
  }
  return records;
}

namespace {

// What rendering and measuring the report's views produced.
struct ViewResults {
  TruthMetrics stored{"views", "captured views", {}};
  TruthMetrics clean{"clean", "clean ground truth", {}};
  json figure_views = json::array();    // pictures per view and band selection
  json viewer_views = json::array();    // band atlases' layout per view
  json viewer_scripts = json::array();  // their script files, relative to the report
};

// Which views the report shows and what to call them.
struct ReportViews {
  std::vector<int> indices;  // into scene.views
  std::string split;         // "test", or "training (...)" when the scene has no test views
};

ReportViews report_views(const io::Scene& scene) {
  if (!scene.test.empty()) return {scene.test, "test"};
  return {scene.train, "training (the scene has no test views)"};
}

// truth | render | error pictures of one view, one per band selection.
json write_view_figures(const fs::path& stage, const std::string& name, const torch::Tensor& render,
                        const torch::Tensor& truth, const std::vector<double>& wl,
                        const ReportOptions& options) {
  json files;
  for (const BandSelection& s : report_band_selections(wl)) {
    std::string rel = "assets/views/" + safe_name(name) + "_" + s.label + ".png";
    io::write_png(stage / rel, comparison_figure(render, truth, wl, s, options.diff_max));
    files[s.label] = rel;
  }
  return {{"name", name}, {"files", files}};
}

// Renders every report view once, measures it against the stored views and
// the clean ground truth, and writes pictures and spectral-viewer data for
// the first few.
ViewResults render_and_measure(const fs::path& stage, const io::Scene& scene,
                               const model::Gaussians& gaussians, const torch::Tensor& background,
                               const std::vector<int>& views, const ReportOptions& options) {
  ViewResults out;
  core::ProgressBar bar("report", int64_t(views.size()));
  for (size_t i = 0; i < views.size(); ++i) {
    const int v = views[i];
    torch::Tensor render = render_view(scene, gaussians, background, v);  // [H, W, N]
    torch::Tensor captured = scene.image(v);                              // [H, W, N]
    torch::Tensor clean_truth = scene.clean_image(v);                     // [H, W, N] or undefined
    const ViewMetrics m = measure_view(scene, v, render);
    out.stored.per_view.push_back(m.stored);
    if (m.clean) out.clean.per_view.push_back(*m.clean);
    const std::string name = scene.views[size_t(v)].name;
    // A view of a band-per-view scene has no whole-spectrum truth to picture
    // beside the render: it is measured, not drawn.
    if (!scene.views[size_t(v)].bands.empty()) {
      bar.update(int64_t(i + 1));
      continue;
    }
    if (int(i) < options.max_views)
      out.figure_views.push_back(write_view_figures(stage, name, render,
                                                    clean_truth.defined() ? clean_truth : captured,
                                                    scene.wavelengths_nm, options));
    if (int(i) < options.viewer_views) {
      std::vector<std::pair<std::string, torch::Tensor>> cubes = {{"render", render},
                                                                  {"views", captured}};
      if (clean_truth.defined()) cubes.emplace_back("clean", clean_truth);
      json meta;
      std::string script = "assets/viewer/" + safe_name(name) + ".js";
      write_viewer_script(stage / script, name, cubes, options.viewer_max_px, meta);
      out.viewer_views.push_back(meta);
      out.viewer_scripts.push_back(script);
    }
    bar.update(int64_t(i + 1));
  }
  bar.finish();
  return out;
}

// The metrics table, the per-band and per-view series, and the spectral
// viewer's sources, from the measured views.
json quality_data(const ViewResults& results, const RunRecords& records) {
  const bool has_clean = !results.clean.per_view.empty();
  json metrics = json::array({results.stored.row("render vs captured views")});
  if (has_clean) metrics.push_back(results.clean.row("render vs clean ground truth"));
  add_eval_rows(records.eval_metrics, metrics);
  std::vector<const TruthMetrics*> truths = {&results.stored};
  if (has_clean) truths.push_back(&results.clean);
  json psnr = json::array(), rmse = json::array(), sam = json::array(), sources = json::array();
  sources.push_back({{"key", "render"}, {"title", "render"}});
  for (const TruthMetrics* t : truths) {
    psnr.push_back({{"label", "vs " + t->title}, {"values", t->mean_band_psnr()}});
    rmse.push_back({{"label", "vs " + t->title}, {"values", t->mean_band_rmse()}});
    sam.push_back({{"label", "vs " + t->title}, {"values", t->sam_per_view()}});
    sources.push_back({{"key", t->key}, {"title", t->title}});
  }
  return {{"metrics", metrics}, {"psnr", psnr}, {"rmse", rmse}, {"sam", sam}, {"sources", sources}};
}

// window.DDHGS_REPORT: everything the page shows except images and the 3D model.
json report_data(const io::Scene& scene, const model::Gaussians& gaussians,
                 const RunRecords& records, const ReportOptions& options, const ReportViews& views,
                 const ViewResults& results) {
  const std::vector<double>& wl = scene.wavelengths_nm;
  const json quality = quality_data(results, records);
  json view_names = json::array();
  for (int v : views.indices) view_names.push_back(scene.views[size_t(v)].name);
  json selection_menu = json::array();
  for (const BandSelection& s : report_band_selections(wl))
    selection_menu.push_back({{"label", s.label}, {"title", selection_title(s, wl)}});
  const bool has_clean = !results.clean.per_view.empty();
  return {{"title", "ddhgs report: " + records.name},
          {"subtitle", std::to_string(gaussians.size()) + " Gaussians, " +
                           std::to_string(scene.bands()) + " bands, " + views.split + " views of " +
                           fs::absolute(scene.root).string()},
          {"wavelengths_nm", wl},
          {"metrics", quality["metrics"]},
          {"metrics_note", metrics_note(records, views.indices.size(), views.split)},
          {"curves", training_curves(records.metrics_log)},
          {"per_band", {{"psnr", quality["psnr"]}, {"rmse", quality["rmse"]}}},
          {"sam_per_view", {{"views", view_names}, {"series", quality["sam"]}}},
          {"figures",
           {{"selections", selection_menu},
            {"views", results.figure_views},
            {"caption", std::string(has_clean ? "clean ground truth" : "captured view") +
                            " | render | |render - truth| (colour bar 0 to " +
                            number(options.diff_max) + " reflectance)"}}},
          {"viewer", {{"views", results.viewer_views}, {"sources", quality["sources"]}}},
          {"views_note",
           scene.band_per_view()
               ? "Each view of this scene holds only some of the bands (a band-per-view scene, "
                 "as a multispectral rig captures it), so there is no whole-spectrum view to "
                 "picture beside the render: the views are measured above, and the 3D view "
                 "shows the model at every wavelength."
               : ""},
          {"viridis", viridis_lut()},
          {"rdylgn", colormap_lut(Colormap::RdYlGn)},
          {"diff_max", options.diff_max},
          {"data_summary", data_summary(scene, gaussians)},
          {"train_summary", records.train_summary},
          {"config", records.config}};
}

// The page with a <script> per spectral-viewer file in place of its placeholder.
std::string page_with_scripts(const ReportAsset& page, const json& scripts) {
  std::string html = page.contents;
  std::string tags;
  for (const json& s : scripts) tags += "<script src=\"" + s.get<std::string>() + "\"></script>\n";
  size_t at = html.find(kViewerScriptsMarker);
  core::require(at != std::string::npos, page.source, "has no viewer-data placeholder");
  return html.replace(at, std::string(kViewerScriptsMarker).size(), tags);
}

// index.html and the static files under assets/ (page script, style, libraries).
void write_static_files(const fs::path& stage, const json& viewer_scripts) {
  for (const ReportAsset& asset : report_assets()) {
    if (asset.name == "index.html")
      io::write_file_atomically(stage / "index.html", page_with_scripts(asset, viewer_scripts));
    else
      io::write_file_atomically(stage / "assets" / asset.name, asset.contents);
  }
}

// The projected CRS's name for the report ("EPSG:32630, WGS 84 / UTM zone 30N").
std::string crs_name(int epsg) {
  std::string name = "EPSG:" + std::to_string(epsg);
  if ((epsg > 32600 && epsg <= 32660) || (epsg > 32700 && epsg <= 32760))
    name += ", WGS 84 / UTM zone " + std::to_string(epsg % 100) + (epsg < 32700 ? "N" : "S");
  return name;
}

constexpr int64_t kReportOrthoMaxPx = 1200;  // the longer side of the report's orthomosaic

// A georeferenced run's orthomosaic (pseudo-RGB) and NDVI map as pictures
// under assets/ortho/, rendered as `render --ortho` renders them at the
// flight's own GSD (coarser when the footprint would exceed
// kReportOrthoMaxPx a side), uncovered pixels mid grey; null when the scene
// has no georeference.
json write_ortho_figures(const fs::path& stage, const io::Scene& scene,
                         const model::Gaussians& gaussians, const torch::Tensor& background) {
  if (!scene.georef) return nullptr;
  const io::Georeference& georef = *scene.georef;
  const Ground ground = model_ground(gaussians, georef);
  OrthoGrid grid = flight_grid(scene, georef, ground, 0);
  const int64_t longest = std::max(grid.width, grid.height);
  if (longest > kReportOrthoMaxPx)
    grid = flight_grid(scene, georef, ground,
                       grid.gsd_m * double(longest) / double(kReportOrthoMaxPx) * 1.001);
  const Orthomosaic mosaic = render_orthomosaic(gaussians, georef, grid, ground, background);
  const torch::Tensor covered = (mosaic.alpha >= float(kOrthoCoveredAlpha)).unsqueeze(2);
  auto shown = [&covered](const torch::Tensor& colours) {
    return core::to_u8(torch::where(covered, colours, torch::full({}, 0.5f)).clamp(0, 1));
  };
  fs::create_directories(stage / "assets" / "ortho");
  json files = json::array();
  io::write_png(stage / "assets" / "ortho" / "reflectance.png",
                shown(picture(mosaic.image.clamp(0, 1), scene.wavelengths_nm, BandSelection{},
                              Colormap::Viridis)));
  files.push_back({{"src", "assets/ortho/reflectance.png"},
                   {"title", "Reflectance orthomosaic (pseudo-RGB of every band)"}});
  std::string ndvi_note;
  try {
    const torch::Tensor map =
        index_band_map(find_vegetation_index("ndvi", "ndvi"), scene.wavelengths_nm);
    const torch::Tensor values = index_values(mosaic.image, map);
    io::write_png(stage / "assets" / "ortho" / "ndvi.png", shown(index_picture(values)));
    files.push_back({{"src", "assets/ortho/ndvi.png"},
                     {"title", "NDVI (NIR - red) / (NIR + red): -1 red, 0 yellow, +1 green"}});
  } catch (const core::Error& e) {
    ndvi_note = std::string(" No NDVI map: ") + e.what() + ".";
  }
  const double covered_share = covered.to(torch::kFloat64).mean().item<double>();
  char corner[64];
  std::snprintf(corner, sizeof corner, "%.2f E %.2f N", grid.left_m, grid.top_m);
  return {
      {"files", files},
      {"caption", "North up. " + std::to_string(grid.width) + " x " + std::to_string(grid.height) +
                      " px at a ground sample distance of " + number(grid.gsd_m) + " m, CRS " +
                      crs_name(georef.epsg) + ", top-left corner " + corner + "; " +
                      std::to_string(int(std::lround(100 * covered_share))) +
                      " % covered (grey: no Gaussian covers the pixel). `ddhgs render RUN "
                      "--ortho` writes the GeoTIFFs." +
                      ndvi_note}};
}

// Writes the whole report into stage (an empty folder).
void build_report(const fs::path& stage, const io::Scene& scene, const model::Gaussians& gaussians,
                  const torch::Tensor& background, const RunRecords& records,
                  const ReportOptions& options) {
  fs::create_directories(stage / "assets" / "views");
  fs::create_directories(stage / "assets" / "viewer");
  const ReportViews views = report_views(scene);
  const ViewResults results =
      render_and_measure(stage, scene, gaussians, background, views.indices, options);
  json data = report_data(scene, gaussians, records, options, views, results);
  data["ortho"] = write_ortho_figures(stage, scene, gaussians, background);
  io::write_file_atomically(stage / "assets" / "data.js",
                            "window.DDHGS_REPORT = " + data.dump() + ";\n");
  json splats = splat_view_data(gaussians, scene, background, views.indices.front());
  io::write_file_atomically(stage / "assets" / "splats.js",
                            "window.DDHGS_SPLATS = " + splats.dump() + ";\n");
  write_static_files(stage, results.viewer_scripts);
}

}  // namespace

fs::path write_report(const io::Scene& scene, const model::Gaussians& gaussians,
                      const torch::Tensor& background, const RunRecords& records,
                      const ReportOptions& options) {
  torch::NoGradGuard no_grad;
  core::require(!scene.views.empty(), scene.root, "the dataset has no views to report on");
  const fs::path out = io::write_folder_atomically(
      {options.out_dir, io::OutputKind::Report, true, options.inputs, ""},
      [&](const fs::path& stage) {
        build_report(stage, scene, gaussians, background, records, options);
      });
  return out / "index.html";
}

}  // namespace ddhgs::eval
