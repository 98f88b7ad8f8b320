// `ddhgs process`, second step: COLMAP's feature extraction, matching and
// mapping as subprocesses, with their output in a log and a progress bar per
// stage.
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <memory>

#include "core/error.h"
#include "core/log.h"
#include "process/process.h"

namespace ddhgs::process {
using namespace io;
namespace fs = std::filesystem;

namespace {

// Stages, in order, and the option sections each accepts.
enum Stage { kExtract = 0, kMatch = 1, kMap = 2 };

std::optional<Stage> stage_of_section(const std::string& section) {
  static const std::map<std::string, Stage> sections = {{"ImageReader", kExtract},
                                                        {"SiftExtraction", kExtract},
                                                        {"SiftMatching", kMatch},
                                                        {"ExhaustiveMatching", kMatch},
                                                        {"SequentialMatching", kMatch},
                                                        {"TwoViewGeometry", kMatch},
                                                        {"Mapper", kMap}};
  auto it = sections.find(section);
  if (it == sections.end()) return std::nullopt;
  return it->second;
}

std::string shell_quote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

// A PATH entry that cannot be read (no permission, a dangling link) is not
// an error: it holds no COLMAP we can run.
bool is_executable(const fs::path& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec) && access(path.c_str(), X_OK) == 0;
}

// "... [3/24] ..." after marker: 3 (done) and 24 (total); false when absent.
bool parse_fraction(const std::string& line, const std::string& marker, int64_t* done,
                    int64_t* total) {
  auto at = line.find(marker);
  if (at == std::string::npos) return false;
  auto open = line.find('[', at);
  if (open == std::string::npos) return false;
  return std::sscanf(line.c_str() + open, "[%ld/%ld", done, total) == 2;
}

// Options of one stage: the defaults, then the user's settings over them
// (COLMAP refuses an option given twice).
using StageOptions = std::map<std::string, std::string>;

std::vector<StageOptions> stage_options(const ColmapOptions& o, const fs::path& images,
                                        const fs::path& work) {
  const std::string db = (work / "database.db").string(), threads = std::to_string(o.threads);
  std::vector<StageOptions> stages(3);
  stages[kExtract] = {{"database_path", db},
                      {"image_path", images.string()},
                      {"ImageReader.camera_model", o.camera_model},
                      {"ImageReader.single_camera", "1"},
                      {"SiftExtraction.use_gpu", "0"},
                      {"SiftExtraction.num_threads", threads},
                      // Small, low-contrast frames: COLMAP's photo threshold
                      // (0.0067) keeps ~130 features per 256x192 view of the
                      // test scene, 0.002 about 600; domain-size pooling
                      // makes their descriptors match reliably. Together
                      // they took the test scene from 2.1 to 0.5 degrees
                      // (docs/benchmarks.md).
                      {"SiftExtraction.peak_threshold", "0.002"},
                      {"SiftExtraction.domain_size_pooling", "1"}};
  stages[kMatch] = {
      {"database_path", db}, {"SiftMatching.use_gpu", "0"}, {"SiftMatching.num_threads", threads}};
  stages[kMap] = {{"database_path", db},
                  {"image_path", images.string()},
                  {"output_path", (work / "sparse").string()},
                  {"Mapper.num_threads", threads},
                  // Hyperspectral frames are small (often 640x512 or less) and
                  // yield a few hundred SIFT features, not thousands: COLMAP's
                  // photo defaults (100 and 30 inliers) leave such captures
                  // without an initial pair or drop views.
                  {"Mapper.init_min_num_inliers", "30"},
                  {"Mapper.abs_pose_min_num_inliers", "15"}};
  for (const auto& setting : o.settings) {
    auto eq = setting.find('=');
    std::string key = setting.substr(0, eq);
    stages[*stage_of_section(key.substr(0, key.find('.')))][key] = setting.substr(eq + 1);
  }
  return stages;
}

struct StageRun {
  std::string command;  // COLMAP subcommand
  std::string label;    // progress bar label
  std::string marker;   // progress line marker
  int64_t total = 0;    // expected progress units
};

// Runs one COLMAP command, appends its output to log, drives a progress bar.
// Returns the exit status and the last line that mentions an error.
int run_stage(const std::string& binary, const StageRun& run, const StageOptions& options,
              std::ofstream& log, std::string* last_error) {
  // glog would write COLMAP's own log files into the system's temporary
  // folder; to stderr they come into this log instead.
  std::string command = "GLOG_logtostderr=1 " + shell_quote(binary) + " " + run.command;
  for (const auto& [key, value] : options) command += " --" + key + " " + shell_quote(value);
  log << "$ " << command << "\n" << std::flush;
  std::unique_ptr<FILE, int (*)(FILE*)> pipe(popen((command + " 2>&1").c_str(), "r"), pclose);
  if (!pipe) throw core::Error(binary + ": could not start COLMAP " + run.command);
  core::ProgressBar bar(run.label, std::max<int64_t>(run.total, 1));
  char buffer[4096];
  int64_t registered = 0;
  while (std::fgets(buffer, sizeof buffer, pipe.get())) {
    std::string line(buffer);
    log << line;
    if (line.find("ERROR") != std::string::npos || line.find("rror:") != std::string::npos ||
        line.find("Check failed") != std::string::npos) {
      *last_error = line.substr(0, line.find_last_not_of("\r\n") + 1);
    }
    int64_t done = 0, total = 0;
    if (run.marker == "Registering image") {
      // Mapper prints "Registering image #id (k)": k images registered so far.
      if (line.find(run.marker) != std::string::npos) bar.update(std::min(++registered, run.total));
    } else if (parse_fraction(line, run.marker, &done, &total) && total > 0) {
      bar.update(done * std::max<int64_t>(run.total, 1) / total);
    }
  }
  log << std::flush;
  int status = pclose(pipe.release());
  bar.finish();
  if (status == -1) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

}  // namespace

void check_colmap_options(const ColmapOptions& options) {
  core::require(options.matcher == "exhaustive" || options.matcher == "sequential",
                "--matcher '" + options.matcher + "': expected exhaustive or sequential");
  // Any model ddhgs reads: a distorting one is undistorted when the scene loads.
  colmap_param_count(options.camera_model, "--camera-model");
  for (const auto& setting : options.settings) {
    auto eq = setting.find('=');
    auto dot = setting.find('.');
    core::require(eq != std::string::npos && dot != std::string::npos && dot < eq && eq > 0,
                  "--colmap-set '" + setting + "': expected Section.key=value");
    core::require(stage_of_section(setting.substr(0, dot)).has_value(),
                  "--colmap-set '" + setting +
                      "': unknown section (expected ImageReader, SiftExtraction, SiftMatching, "
                      "ExhaustiveMatching, SequentialMatching, TwoViewGeometry or Mapper)");
  }
}

std::string find_colmap(const ColmapOptions& options) {
  std::string name = options.binary;
  if (name.empty()) {
    const char* env = std::getenv("DDHGS_COLMAP");
    name = env && *env ? env : "colmap";
  }
  const std::string how =
      "install it (Debian/Ubuntu: apt-get install colmap, or scripts/setup.sh) or name the "
      "executable with --colmap PATH or DDHGS_COLMAP";
  if (name.find('/') != std::string::npos) {
    core::require(is_executable(name), name, "is not an executable COLMAP; " + how);
    return fs::absolute(name).string();
  }
  const char* path = std::getenv("PATH");
  std::string dirs = path ? path : "";
  size_t start = 0;
  while (start <= dirs.size()) {
    size_t end = dirs.find(':', start);
    if (end == std::string::npos) end = dirs.size();
    fs::path candidate = fs::path(dirs.substr(start, end - start)) / name;
    if (end > start && is_executable(candidate)) return candidate.string();
    start = end + 1;
  }
  throw core::Error(name + ": COLMAP not found on PATH; " + how);
}

void run_colmap(const ColmapOptions& options, const fs::path& images_dir, const fs::path& work,
                const fs::path& log_path) {
  check_colmap_options(options);
  std::string binary = find_colmap(options);
  fs::create_directories(work / "sparse");
  // COLMAP links Qt; without a display it must not try to open one.
  setenv("QT_QPA_PLATFORM", "offscreen", 0);
  int64_t views = 0;
  for (const auto& entry : fs::directory_iterator(images_dir)) views += entry.is_regular_file();

  std::vector<StageOptions> stages = stage_options(options, images_dir, work);
  const bool sequential = options.matcher == "sequential";
  const std::vector<StageRun> runs = {
      {"feature_extractor", "colmap features", "Processed file", views},
      {sequential ? "sequential_matcher" : "exhaustive_matcher", "colmap matching",
       sequential ? "Matching image" : "Matching block", views},
      {"mapper", "colmap mapping", "Registering image", views}};
  std::ofstream log(log_path, std::ios::app);
  core::require(bool(log), log_path, "cannot write the COLMAP log");
  for (size_t s = 0; s < runs.size(); ++s) {
    std::string last_error;
    int status = run_stage(binary, runs[s], stages[s], log, &last_error);
    if (status == 0) continue;
    std::string why = last_error.empty() ? "exit status " + std::to_string(status) : last_error;
    if (s == kMap)
      throw core::Error(log_path, "COLMAP registered fewer than 3 views, no model (" + why + ")");
    throw core::Error(log_path, "COLMAP " + runs[s].command + " failed (" + why + ")");
  }
}

std::optional<size_t> largest_model(const std::vector<ColmapModel>& models) {
  std::optional<size_t> best;
  for (size_t i = 0; i < models.size(); ++i) {
    if (!best) {
      best = i;
      continue;
    }
    const auto& a = models[i];
    const auto& b = models[*best];
    if (a.images.size() > b.images.size() ||
        (a.images.size() == b.images.size() && a.points.size() > b.points.size()))
      best = i;
  }
  return best;
}

}  // namespace ddhgs::process
