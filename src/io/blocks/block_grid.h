// Blocks of a flight too large for one machine: the ground frame the flight
// is cut in, the grid of cells over its footprint, and BLOCKS/blocks.json,
// which `ddhgs partition` writes and `ddhgs merge` reads
// (docs/data-formats.md).
#pragma once
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/mat.h"

namespace ddhgs::io {

// A frame on the ground: origin on it, u along the flight, v across, n the
// ground's normal towards the cameras (u, v, n right-handed, orthonormal).
struct GroundFrame {
  core::Vec3 origin, u{1, 0, 0}, v{0, 1, 0}, n{0, 0, 1};
  // A world point's coordinates along u and v (scene units).
  double along(const core::Vec3& p) const { return (p - origin).dot(u); }
  double across(const core::Vec3& p) const { return (p - origin).dot(v); }
};

// A rectangle in ground coordinates, [u0, u1] x [v0, v1].
struct GroundBox {
  double u0 = 0, u1 = 0, v0 = 0, v1 = 0;
  double area() const;
  // The area this box shares with another (0 when apart).
  double shared(const GroundBox& other) const;
  bool contains(double u, double v) const { return u >= u0 && u <= u1 && v >= v0 && v <= v1; }
};

// rows x cols equal cells over the footprint (rows across v, columns along
// u); a cell's block holds it plus a margin of `overlap` of its size on
// every side.
struct BlockGrid {
  GroundFrame frame;
  GroundBox footprint;
  int rows = 1, cols = 1;
  double overlap = 0.2;

  int blocks() const { return rows * cols; }
  GroundBox cell(int block) const;      // block = row * cols + col
  GroundBox margined(int block) const;  // the cell and its margin
  // The block whose cell holds ground point (u, v); points beyond the
  // footprint belong to the nearest edge cell, so every point has one.
  int block_of(double u, double v) const;
  // How much of block `block`'s model to keep at ground point (u, v) when
  // neighbouring blocks are cross-faded across their shared border: 1 deep in
  // the cell, 1/2 on a border between two cells, 0 from `blend` of the
  // margin beyond it, linear in between, the product of the ramps along u and
  // along v. Across the footprint's outer edges there is no ramp. A ramp's
  // half-width is blend x the margin, at most half the cell, so the blocks'
  // weights at any point sum to 1. blend 0 (or no overlap): 1 in the cell
  // (block_of), else 0.
  double blend_weight(int block, double u, double v, double blend) const;
};

// "block_00", "block_01", ...: block folder names, as wide as the count needs.
std::string block_name(int block, int blocks);

struct BlockRecord {
  std::string name;  // folder under BLOCKS/
  int row = 0, col = 0;
  std::vector<std::string> train_views, test_views;  // the scene's file paths
  int64_t points = 0;
};

struct BlocksFile {
  std::filesystem::path scene;  // the partitioned scene, absolute
  BlockGrid grid;
  std::vector<BlockRecord> blocks;  // in block order
};

void write_blocks_file(const std::filesystem::path& path, const BlocksFile& file);
// core::Error naming the file and the key when it is malformed.
BlocksFile read_blocks_file(const std::filesystem::path& path);

// BLOCK/block.json, which partition writes into each block's scene folder:
// where the block lies in its flight, so that `ddhgs train` can train it as
// the flight's own model would have trained that ground (train/trainer.h:
// data.block_as_flight).
struct BlockContext {
  std::string name;  // the block's folder name
  GroundFrame frame;
  GroundBox cell, margined;
  int64_t flight_train_views = 0;  // the whole flight's training views
  double flight_extent = 0;        // io::scene_extent of those views
  // The flight's backdrop (io::flight_backdrop), one value per band: a
  // block whose run learns its background draws over this one instead, the
  // same for every block (a background learned from a block's own pixels
  // settles differently in each, and so does what its Gaussians cover).
  // Empty in a block.json written before 2026-12-08: the block learns its own.
  std::vector<double> background;
};
constexpr const char* kBlockContextFile = "block.json";
void write_block_context(const std::filesystem::path& path, const BlockContext& context);
// The context of the scene folder `scene_root`, if it has a block.json;
// core::Error naming the file and the key when it is malformed.
std::optional<BlockContext> read_block_context(const std::filesystem::path& scene_root);

}  // namespace ddhgs::io
