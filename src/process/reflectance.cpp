#include "process/reflectance.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <limits>
#include <sstream>

#include "core/error.h"
#include "core/log.h"
#include "core/text.h"
#include "io/files/atomic_file.h"
#include "io/scene/scene.h"

namespace ddhgs::process {
namespace fs = std::filesystem;

namespace {

// The whole of text as a finite number, or none.
std::optional<double> number(const std::string& text) {
  const std::string t = core::trim(text);
  if (t.empty()) return std::nullopt;
  size_t used = 0;
  double value = 0;
  try {
    value = std::stod(t, &used);
  } catch (const std::exception&) {
    return std::nullopt;
  }
  if (used != t.size() || !std::isfinite(value)) return std::nullopt;
  return value;
}

// The rows of a white-reflectance file: each line's comma- (or space-)
// separated numbers; a first line that is not numbers is a header.
std::vector<std::vector<double>> number_rows(const fs::path& path) {
  std::istringstream in(io::read_file(path));
  std::vector<std::vector<double>> rows;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    for (char& c : line)
      if (c == ',' || c == ';' || c == '\t') c = ' ';
    if (core::trim(line).empty() || core::trim(line)[0] == '#') continue;  // blank, comment
    std::istringstream fields(line);
    std::vector<double> row;
    std::string field;
    bool numbers = true;
    while (fields >> field) {
      const std::optional<double> v = number(field);
      numbers = numbers && v.has_value();
      if (v) row.push_back(*v);
    }
    if (!numbers && rows.empty() && line_no == 1) continue;  // a header
    core::require(numbers && (row.size() == 1 || row.size() == 2), path,
                  "line " + std::to_string(line_no) +
                      ": expected one reflectance, or wavelength_nm,reflectance");
    if (!rows.empty() && rows.front().size() != row.size())
      throw core::Error(path, "line " + std::to_string(line_no) + " has " +
                                  std::to_string(row.size()) + " numbers, the first line " +
                                  std::to_string(rows.front().size()));
    rows.push_back(row);
  }
  core::require(!rows.empty(), path, "holds no reflectance values");
  return rows;
}

// Linear interpolation of (x, y) rows, x ascending, at `at`; core::Error
// naming path when `at` lies outside them.
double interpolate(const std::vector<std::vector<double>>& rows, double at, const fs::path& path) {
  for (size_t i = 0; i + 1 < rows.size(); ++i) {
    const double x0 = rows[i][0], x1 = rows[i + 1][0];
    if (at >= x0 && at <= x1) {
      const double t = x1 > x0 ? (at - x0) / (x1 - x0) : 0;
      return rows[i][1] + t * (rows[i + 1][1] - rows[i][1]);
    }
  }
  if (rows.size() == 1 && std::abs(at - rows[0][0]) < 1e-9) return rows[0][1];
  throw core::Error(path, "covers " + core::format_g(rows.front()[0]) + "-" +
                              core::format_g(rows.back()[0]) + " nm, not the band at " +
                              core::format_g(at) + " nm");
}

void require_reflectance(double value, const std::string& where) {
  core::require(value > 0 && value <= 2, where,
                "a white reference's reflectance must lie in (0, 2], got " + core::format_g(value));
}

}  // namespace

std::vector<double> parse_white_reflectance(const std::string& spec,
                                            const std::vector<double>& wavelengths_nm) {
  const size_t bands = wavelengths_nm.size();
  if (const std::optional<double> value = number(spec)) {
    require_reflectance(*value, "--white-reflectance");
    return std::vector<double>(bands, *value);
  }
  const fs::path path(spec);
  core::require(fs::is_regular_file(path), "--white-reflectance",
                "'" + spec + "' is neither a number nor a file");
  const std::vector<std::vector<double>> rows = number_rows(path);
  std::vector<double> out;
  if (rows.front().size() == 1) {
    core::require(rows.size() == bands, path,
                  "holds " + std::to_string(rows.size()) + " values; the cubes have " +
                      std::to_string(bands) + " bands");
    for (const auto& row : rows) out.push_back(row[0]);
  } else {
    for (size_t i = 1; i < rows.size(); ++i)
      core::require(rows[i][0] > rows[i - 1][0], path, "wavelengths must increase, line by line");
    for (double nm : wavelengths_nm) out.push_back(interpolate(rows, nm, path));
  }
  for (double v : out) require_reflectance(v, path.string());
  return out;
}

torch::Tensor read_reference(const fs::path& path, int64_t width, int64_t bands) {
  io::Cube cube = io::read_cube(path);
  // A reference of a few lines looks band-first to the layout guess of
  // .npy and .pt files (2 x 640 x 141): the cubes' shape decides.
  for (io::BandLayout layout : {io::BandLayout::BandsLast, io::BandLayout::BandsFirst}) {
    if (cube.bands() == bands && cube.width() == width) break;
    io::Cube other = io::read_cube(path, {layout});
    if (other.bands() == bands && other.width() == width) cube = std::move(other);
  }
  core::require(cube.bands() == bands, path,
                "a reference of " + std::to_string(cube.bands()) + " bands for cubes of " +
                    std::to_string(bands));
  core::require(cube.width() == width, path,
                "a reference " + std::to_string(cube.width()) + " pixels wide for cubes " +
                    std::to_string(width) + " wide (one value per column is needed)");
  // Counts as stored, whatever the file's scale: raw, white and dark share units.
  return io::cube_to_float(cube, 1.0).to(torch::kFloat64).mean(0);  // [W, B]
}

std::optional<double> top_count(io::SampleType type) {
  switch (type) {
    case io::SampleType::U8:
      return 255.0;
    case io::SampleType::U16:
      return 65535.0;
    case io::SampleType::I16:
      return 32767.0;
    case io::SampleType::I32:
      return double(std::numeric_limits<int32_t>::max());
    default:
      return std::nullopt;
  }
}

torch::Tensor to_reflectance(const io::Cube& raw, const torch::Tensor& white,
                             const torch::Tensor& dark,
                             const std::vector<double>& white_reflectance,
                             std::optional<double> saturation, ReflectanceCounts* counts) {
  const int64_t w = raw.width(), b = raw.bands();
  core::require(white.sizes() == torch::IntArrayRef({w, b}) &&
                    dark.sizes() == torch::IntArrayRef({w, b}) &&
                    int64_t(white_reflectance.size()) == b,
                "reflectance: references of another shape than the cube");
  const torch::Tensor counts_raw = io::cube_to_float(raw, 1.0).to(torch::kFloat64);  // [H, W, B]
  const torch::Tensor span = white - dark;                                           // [W, B]
  // Per band: the median span over the columns; a column far below it is dead.
  const torch::Tensor typical = std::get<0>(span.median(0, true));  // [1, B]
  const torch::Tensor dead = (span <= 0) | (span <= kDeadReferenceShare * typical);
  const torch::Tensor rho = torch::tensor(white_reflectance, torch::kFloat64);  // [B]
  const torch::Tensor gain = torch::where(dead, torch::zeros_like(span), rho / span);
  const torch::Tensor reflectance = (counts_raw - dark) * gain;  // [H, W, B]
  if (counts) {
    counts->samples = counts_raw.numel();
    counts->dead = dead.sum().item<int64_t>();
    counts->saturated = saturation ? (counts_raw >= *saturation).sum().item<int64_t>() : 0;
  }
  return reflectance.to(torch::kFloat32).contiguous();
}

bool calibrates(const CubeSet& cubes, const ReflectanceOptions& options) {
  return !options.white.empty() || !cubes.white_refs.empty();
}

Calibration plan_calibration(const CubeSet& cubes, const ReflectanceOptions& options) {
  core::require(options.white.empty() == options.dark.empty(),
                "--white and --dark: give both references, or neither");
  Calibration c;
  c.white_reflectance = parse_white_reflectance(options.white_reflectance, cubes.wavelengths_nm);
  c.saturation = options.saturation;
  if (!options.white.empty()) {
    if (!cubes.white_refs.empty())
      core::log_info("process: --white and --dark replace the captures' own references");
    c.given_white = read_reference(options.white, cubes.width, cubes.bands);
    c.given_dark = read_reference(options.dark, cubes.width, cubes.bands);
    c.white.assign(cubes.files.size(), options.white);
    c.dark.assign(cubes.files.size(), options.dark);
    return c;
  }
  c.white = cubes.white_refs;
  c.dark = cubes.dark_refs;
  // Headers only here; each capture's references are read with its cube.
  for (const auto& list : {c.white, c.dark})
    for (const fs::path& ref : list) {
      const io::CubeInfo info = io::probe_cube(ref);
      core::require(info.bands == cubes.bands, ref,
                    "a reference of " + std::to_string(info.bands) + " bands for cubes of " +
                        std::to_string(cubes.bands));
      core::require(info.width == cubes.width, ref,
                    "a reference " + std::to_string(info.width) + " pixels wide for cubes " +
                        std::to_string(cubes.width) + " wide (one value per column is needed)");
    }
  return c;
}

CubeSet write_reflectance_cubes(const CubeSet& cubes, const Calibration& calibration,
                                const fs::path& dir, nlohmann::json& summary) {
  fs::create_directories(dir);
  CubeSet out = cubes;
  out.files.clear();
  out.white_refs.clear();
  out.dark_refs.clear();
  ReflectanceCounts total;
  std::optional<double> top;
  int saturated_cubes = 0;
  nlohmann::json per_cube = nlohmann::json::array();
  core::ProgressBar bar("reflectance", int64_t(cubes.files.size()));
  for (size_t i = 0; i < cubes.files.size(); ++i) {
    const io::Cube raw = io::read_cube(cubes.files[i]);
    io::require_bands(cubes.files[i], raw.bands(), cubes.bands);
    const bool given = calibration.given_white.defined();
    const torch::Tensor white =
        given ? calibration.given_white
              : read_reference(calibration.white[i], raw.width(), raw.bands());
    const torch::Tensor dark = given
                                   ? calibration.given_dark
                                   : read_reference(calibration.dark[i], raw.width(), raw.bands());
    top = calibration.saturation ? calibration.saturation : top_count(raw.type);
    ReflectanceCounts counts;
    const torch::Tensor reflectance =
        to_reflectance(raw, white, dark, calibration.white_reflectance, top, &counts);
    out.files.push_back(dir / (cubes.names[i] + ".npy"));
    io::write_npy(out.files.back(), reflectance);
    total.samples += counts.samples;
    total.saturated += counts.saturated;
    total.dead += counts.dead;
    saturated_cubes += counts.saturated > 0;
    per_cube.push_back(
        {{"name", cubes.names[i]}, {"saturated", counts.saturated}, {"dead", counts.dead}});
    bar.update(int64_t(i + 1));
  }
  bar.finish();
  const bool given = calibration.given_white.defined();
  const double share = total.samples ? double(total.saturated) / double(total.samples) : 0;
  summary["reflectance"] = {
      {"formula", "(raw - dark) / (white - dark) x white reflectance, per band and pixel"},
      {"white", given ? calibration.white.front().string() : "each capture's WHITEREF_*"},
      {"dark", given ? calibration.dark.front().string() : "each capture's DARKREF_*"},
      {"references", "averaged over their rows: one value per column and band"},
      {"white_reflectance", calibration.white_reflectance},
      {"saturation_count", top ? nlohmann::json(*top) : nlohmann::json()},
      {"saturated_samples", total.saturated},
      {"saturated_share", share},
      {"dead_reference_pixels", total.dead},
      {"dead", "columns x bands whose white - dark is at most 0 or under " +
                   core::format_g(100 * kDeadReferenceShare) +
                   " % of the band's median; their reflectance is 0"},
      {"cubes", per_cube}};
  const std::string line =
      "process: reflectance from white and dark references (averaged over their rows: one per "
      "column and band): " +
      std::to_string(total.saturated) + " saturated samples (" + core::format_g(100 * share) +
      " %) in " + std::to_string(saturated_cubes) + " of " + std::to_string(cubes.files.size()) +
      " cubes" + (top ? " at count " + core::format_g(*top) : std::string()) + ", " +
      std::to_string(total.dead) +
      " dead reference pixels (column x band, over the cubes) set to 0";
  if (total.saturated > 0 || total.dead > 0)
    core::log_warn(line);
  else
    core::log_info(line);
  return out;
}

}  // namespace ddhgs::process
