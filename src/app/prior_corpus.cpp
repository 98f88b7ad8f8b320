#include "app/prior_corpus.h"

#include <map>
#include <set>
#include <string>

#include "app/trained_run.h"
#include "core/error.h"
#include "core/log.h"
#include "eval/evaluate.h"
#include "io/files/atomic_file.h"

namespace ddhgs::app {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

struct Entry {
  fs::path scene, run;
};

// The manifest's entries whose run finished (train_summary.json written).
std::vector<Entry> finished_entries(const fs::path& corpus, size_t& unfinished) {
  const fs::path manifest = corpus / "manifest.json";
  core::require(fs::exists(manifest), manifest,
                "missing: not a prior corpus (scripts/prior_corpus.sh writes one)");
  const json j = json::parse(io::read_file(manifest), nullptr, false);
  core::require(j.is_object() && j.contains("entries") && j["entries"].is_array(), manifest,
                "expected {\"entries\": [{\"scene\": ..., \"run\": ...}, ...]}");
  std::vector<Entry> entries;
  unfinished = 0;
  for (const json& e : j["entries"]) {
    core::require(e.is_object() && e.contains("scene") && e["scene"].is_string() &&
                      e.contains("run") && e["run"].is_string(),
                  manifest, "every entry needs \"scene\" and \"run\" folder names");
    const Entry entry{corpus / e["scene"].get<std::string>(), corpus / e["run"].get<std::string>()};
    core::require(fs::is_directory(entry.scene), manifest,
                  "entry scene " + entry.scene.string() + " is not a folder");
    if (fs::exists(entry.run / "train_summary.json"))
      entries.push_back(entry);
    else
      ++unfinished;
  }
  return entries;
}

}  // namespace

PriorCorpus load_prior_corpus(const fs::path& corpus, int64_t channels, int check_every) {
  size_t unfinished = 0;
  const std::vector<Entry> entries = finished_entries(corpus, unfinished);
  core::require(!entries.empty(), corpus / "manifest.json", "no entry has a finished run yet");
  PriorCorpus out;
  std::set<int64_t> band_counts;
  std::map<std::string, int> sizes;
  size_t check_entries = 0;
  core::ProgressBar bar("prior corpus", int64_t(entries.size()));
  for (size_t i = 0; i < entries.size(); ++i) {
    const bool last = i + 1 == entries.size();
    const bool is_check =
        entries.size() > 1 && ((i + 1) % size_t(check_every) == 0 || (last && check_entries == 0));
    TrainedRun run = open_trained_run(entries[i].run, entries[i].scene.string());
    const io::Scene& scene = *run.scene;
    core::require(scene.has_clean(), scene.root, "has no clean truth (clean/) to learn from");
    core::require(!scene.test.empty(), scene.root, "has no held-out views to learn from");
    const model::SpectralSubspace subspace = train::fit_scene_subspace(scene, channels);
    torch::NoGradGuard no_grad;
    for (int v : scene.test) {
      const torch::Tensor render = eval::render_view(scene, run.gaussians, run.background, v);
      const torch::Tensor truth = scene.clean_image(v);
      if (is_check)
        out.checks.push_back({render, truth, subspace});
      else
        out.pairs.push_back({subspace.encode(render), subspace.encode(truth)});
      sizes[std::to_string(render.size(1)) + "x" + std::to_string(render.size(0))]++;
    }
    check_entries += is_check;
    band_counts.insert(scene.bands());
    bar.update(int64_t(i + 1));
  }
  bar.finish();
  core::require(!out.pairs.empty(), corpus / "manifest.json",
                "needs at least two finished entries (one is kept for checks)");
  out.description = {{"entries", entries.size()},
                     {"unfinished_entries", unfinished},
                     {"check_entries", check_entries},
                     {"pairs", out.pairs.size()},
                     {"check_views", out.checks.size()},
                     {"band_counts", band_counts},
                     {"view_sizes", sizes}};
  return out;
}

}  // namespace ddhgs::app
