// Helpers of the reliability suite: runs of the ddhgs executable and views
// of what a command left on disk. Every folder a test writes or points a
// destructive command at lies inside test::temp_dir.
#pragma once
#include <algorithm>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "io/files/atomic_file.h"
#include "support/test_support.h"

namespace ddhgs::test {

// Runs `ddhgs ARGS`; stdout and stderr together in *out.
inline int ddhgs(const std::string& args, std::string* out) {
  return run_command(ddhgs_binary() + " " + args, out);
}

// A JSON file a command wrote, parsed.
inline nlohmann::json read_json(const std::filesystem::path& path) {
  return nlohmann::json::parse(io::read_file(path));
}

// Every file below dir with its contents, to show that nothing changed.
inline std::vector<std::pair<std::string, std::string>> snapshot(const std::filesystem::path& dir) {
  std::vector<std::pair<std::string, std::string>> files;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(dir))
    if (entry.is_regular_file())
      files.emplace_back(std::filesystem::relative(entry.path(), dir).string(),
                         io::read_file(entry.path()));
  std::sort(files.begin(), files.end());
  return files;
}

inline size_t lines(const std::string& text) {
  return size_t(std::count(text.begin(), text.end(), '\n'));
}

// The lines of text that start with "error: ".
inline std::vector<std::string> error_lines(const std::string& text) {
  std::vector<std::string> found;
  size_t start = 0;
  while (start < text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    if (text.compare(start, 7, "error: ") == 0) found.push_back(text.substr(start, end - start));
    start = end + 1;
  }
  return found;
}

// Temporaries of atomic writes (".NAME.tmp-PID-N") below dir.
inline std::vector<std::string> temporaries(const std::filesystem::path& dir) {
  std::vector<std::string> found;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(dir))
    if (entry.path().filename().string().find(".tmp-") != std::string::npos)
      found.push_back(entry.path().string());
  return found;
}

// A 12-view, 4-band, 32x24 demo scene: 11 training views and view r_010 held out.
const std::string kTinyScene = " synth --preset demo --width 32 --height 24 --bands 4 --views 12";
const std::string kQuickTrain = " --preset demo --iterations 20 --checkpoint-every 0";

// kTinyScene, written once per test process; tests must not modify it.
inline const std::filesystem::path& tiny_scene() {
  static const std::filesystem::path dir = [] {
    std::filesystem::path d = temp_dir("tiny_scene") / "scene";
    std::string out;
    if (ddhgs("-q" + kTinyScene + " --out " + d.string(), &out) != 0)
      throw std::runtime_error("cannot write the tiny scene: " + out);
    return d;
  }();
  return dir;
}

// `scripts/prior_corpus.sh OUT COUNT` with this build's ddhgs, the drawn
// sizes divided by `downsize` and runs of `iters` iterations.
inline std::string prior_corpus_command(const std::filesystem::path& out, const std::string& count,
                                        int downsize, int iters) {
  return "DDHGS=" + ddhgs_binary() + " PYTHON=" + python() +
         " DOWNSIZE=" + std::to_string(downsize) + " ITERS=" + std::to_string(iters) + " bash " +
         (source_dir() / "scripts" / "prior_corpus.sh").string() + " " + out.string() + " " + count;
}

// `ddhgs process SYNTH/captures --rig FLAGS --skip-colmap --poses
// SYNTH/truth/transforms.json --out SCENE`: a synthetic rig's captures posed
// by its reference camera's true poses (COLMAP does not pose small rigs).
inline int process_with_true_poses(const std::filesystem::path& synth,
                                   const std::filesystem::path& scene, const std::string& flags,
                                   std::string* out) {
  return ddhgs("process " + (synth / "captures").string() + " --rig " + flags +
                   " --skip-colmap --poses " + (synth / "truth" / "transforms.json").string() +
                   " --out " + scene.string(),
               out);
}

}  // namespace ddhgs::test
