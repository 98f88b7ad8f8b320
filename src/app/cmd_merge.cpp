// `ddhgs merge BLOCKS --out RUN`: the trained blocks of `ddhgs partition`
// joined into one run folder (app/block_merge.h).
#include <memory>

#include "app/block_merge.h"
#include "app/registry.h"
#include "core/log.h"

namespace ddhgs::app {
namespace cmd_merge {

struct MergeArgs {
  MergeOptions options;
  std::string blocks, out;
};

Action setup(CLI::App& parent) {
  auto args = std::make_shared<MergeArgs>();
  CLI::App* cmd = parent.add_subcommand(
      "merge",
      "Join the trained blocks of ddhgs partition into one run folder (each block's Gaussians "
      "in its own cell, neighbours cross-faded across their overlap)");
  cmd->add_option("blocks", args->blocks, "The partition's folder (holding blocks.json)")
      ->required();
  cmd->add_option("--out", args->out, "The merged run folder")->required();
  cmd->add_option("--runs", args->options.runs,
                  "Where each block's run is, {block} standing for its folder name "
                  "(runs/{block}); default BLOCKS/{block}/run");
  cmd->add_option("--seam-blend", args->options.blend,
                  "Share of each overlap over which neighbouring blocks' Gaussians are "
                  "cross-faded (their opacities weighed by a ramp across the border); 0: each "
                  "block keeps only its own cell")
      ->default_val(1.0)
      ->check(within(0, 1));
  cmd->add_flag("--force", args->options.force, "Replace an earlier merged run");
  return [args] {
    MergeOptions options = args->options;
    options.blocks = args->blocks;
    options.out = args->out;
    const MergeSummary s = merge_blocks(options);
    for (size_t b = 0; b < s.kept.size(); ++b)
      core::log_info("merge: block " + std::to_string(b) + ": kept " + std::to_string(s.kept[b]) +
                     " of " + std::to_string(s.trained[b]) + " Gaussians, " +
                     std::to_string(s.faded[b]) +
                     " of them faded across the seams (the rest lie in other blocks' cells)");
    core::log_info("merge: " + std::to_string(s.gaussians) + " Gaussians -> " + args->out);
    return 0;
  };
}

const Registrar registrar("merge", 36, setup);

}  // namespace cmd_merge
}  // namespace ddhgs::app
