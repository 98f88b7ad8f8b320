// `ddhgs partition SCENE --blocks N|RxC --out BLOCKS`: a flight too large for
// one machine cut into overlapping blocks over its ground footprint, each an
// ordinary scene for `ddhgs train`; `ddhgs merge` joins the trained blocks.
#include <memory>
#include <regex>

#include "app/registry.h"
#include "core/error.h"
#include "core/log.h"
#include "core/text.h"
#include "io/blocks/partition.h"

namespace ddhgs::app {
namespace cmd_partition {

struct PartitionArgs {
  std::string blocks = "4";
  io::PartitionOptions options;
  std::string scene, out;
};

// "4": that many cells, shaped by the footprint; "2x3": 2 rows, 3 columns.
void parse_blocks(const std::string& text, io::PartitionOptions& options) {
  std::smatch m;
  const auto fail = [&] {
    throw core::Error("--blocks " + core::quoted_value(text) +
                      ": expected a count (4) or rows x columns (2x2), 1 to 10000 blocks");
  };
  auto number = [&](const std::string& digits) {
    if (digits.size() > 5) fail();
    return std::stoi(digits);
  };
  if (std::regex_match(text, m, std::regex("([0-9]+)"))) {
    options.rows = options.cols = 0;
    options.blocks = number(m[1]);
  } else if (std::regex_match(text, m, std::regex("([0-9]+)[xX]([0-9]+)"))) {
    options.rows = number(m[1]);
    options.cols = number(m[2]);
    options.blocks = options.rows * options.cols;
  } else {
    fail();
  }
  if (options.blocks < 1 || options.blocks > 10000 || (options.rows == 0) != (options.cols == 0) ||
      (options.rows > 0 && options.cols < 1))
    fail();
}

Action setup(CLI::App& parent) {
  auto args = std::make_shared<PartitionArgs>();
  CLI::App* cmd = parent.add_subcommand(
      "partition",
      "Cut a flight's scene into overlapping blocks over its ground footprint, each a scene "
      "to train on its own (then ddhgs merge)");
  cmd->add_option("scene", args->scene, "Scene folder with a transforms.json")->required();
  cmd->add_option("--out", args->out, "Output folder: BLOCKS/block_NN/ scenes and blocks.json")
      ->required();
  cmd->add_option("--blocks", args->blocks,
                  "How many blocks: a count (the grid's shape follows the footprint) or rows x "
                  "columns (2x3)")
      ->capture_default_str();
  cmd->add_option("--overlap", args->options.overlap,
                  "Margin each block adds on every side, of its cell's size (0.2: 20 %)")
      ->capture_default_str();
  cmd->add_flag("--force", args->options.force, "Replace an earlier partition's output folder");
  return [args] {
    io::PartitionOptions options = args->options;
    parse_blocks(args->blocks, options);
    options.scene = args->scene;
    options.out = args->out;
    const io::BlocksFile file = io::partition_scene(options);
    core::log_info("partition: " + std::to_string(file.grid.rows) + "x" +
                   std::to_string(file.grid.cols) + " blocks of " + args->scene + " -> " +
                   args->out + " (blocks.json)");
    return 0;
  };
}

const Registrar registrar("partition", 35, setup);

}  // namespace cmd_partition
}  // namespace ddhgs::app
