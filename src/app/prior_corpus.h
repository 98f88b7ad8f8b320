// The corpus a denoiser prior learns from (scripts/prior_corpus.sh writes
// it): CORPUS/manifest.json lists entries, each a synthetic scene with clean
// truth and a short training run on it. Every held-out view of a finished
// run gives one pair: its render by the run's Gaussians and the clean truth,
// as the scene's subspace coefficients (train/denoiser_prior.h).
#pragma once
#include <nlohmann/json.hpp>

#include <filesystem>
#include <vector>

#include "train/denoiser_prior.h"

namespace ddhgs::app {

struct PriorCorpus {
  std::vector<train::PriorPair> pairs;        // from the training entries
  std::vector<train::PriorCheckView> checks;  // the check entries' views
  // For the prior's record: entries used, skipped (unfinished runs), pairs
  // and check views, band counts and sizes seen.
  nlohmann::json description;
};

// Every check_every-th finished entry (the last one when there are fewer)
// is kept for checks, never trained on. core::Error naming the file when
// the manifest is missing or malformed, an entry's folders are missing, or
// no entry has a finished run with clean truth; a finished entry without
// clean truth or held-out views is one error naming its scene.
PriorCorpus load_prior_corpus(const std::filesystem::path& corpus, int64_t channels,
                              int check_every = 10);

}  // namespace ddhgs::app
