// `ddhgs merge`: the trained blocks of a partition (io/blocks/partition.h)
// joined into one run folder. Each block keeps the Gaussians whose centres
// lie in its own cell, and across a border with a neighbour the two are
// cross-faded over their overlap (MergeOptions::blend); the merged run's
// dataset is the partitioned scene, so `eval` measures every held-out view
// of the flight and `render`, `report` and `export` read it as any run.
#pragma once
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace ddhgs::app {

struct MergeOptions {
  std::filesystem::path blocks;  // BLOCKS (blocks.json)
  std::filesystem::path out;     // the merged run
  // Where each block's run is: "{block}" stands for its folder name
  // (block_00, ...); relative paths are from the current folder. Empty:
  // BLOCKS/{block}/run.
  std::string runs;
  // The share of each overlap over which neighbouring blocks' Gaussians are
  // cross-faded (io::BlockGrid::blend_weight: each Gaussian's opacity times
  // its block's weight at its centre); 0 keeps each block's Gaussians in its
  // own cell and nothing else (a hard cut at the cell borders).
  double blend = 1.0;
  bool force = false;
};

// The run folder of block `name` under options (runs pattern, or the default).
std::filesystem::path block_run(const MergeOptions& options, const std::string& name);

struct MergeSummary {
  // Gaussians per block: its run's, those kept (weight above 0) and, of
  // those, the ones faded (weight under 1).
  std::vector<int64_t> trained, kept, faded;
  int64_t gaussians = 0;
};

// Writes options.out (io::write_folder_atomically: all or nothing):
// gaussians.ply, config.json (the first block's, with data.path the
// partitioned scene), background.json (the blocks' mean, when learned),
// rig_corrections.json (the blocks' mean, when they learned them) and
// train_summary.json (the blocks' summaries, their summed seconds and
// largest peak memory). core::Error naming the run or file: a block's run
// missing or unfinished, blocks that disagree in bands, wavelengths, SH
// degree or colour model form.
MergeSummary merge_blocks(const MergeOptions& options);

}  // namespace ddhgs::app
