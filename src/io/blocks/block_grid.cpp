#include "io/blocks/block_grid.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <tuple>

#include "core/error.h"
#include "io/files/atomic_file.h"
#include "io/files/input_file.h"

namespace ddhgs::io {
namespace fs = std::filesystem;
using json = nlohmann::json;

double GroundBox::area() const {
  return std::max(0.0, u1 - u0) * std::max(0.0, v1 - v0);
}

double GroundBox::shared(const GroundBox& o) const {
  return GroundBox{std::max(u0, o.u0), std::min(u1, o.u1), std::max(v0, o.v0), std::min(v1, o.v1)}
      .area();
}

GroundBox BlockGrid::cell(int block) const {
  const int row = block / cols, col = block % cols;
  const double du = (footprint.u1 - footprint.u0) / cols;
  const double dv = (footprint.v1 - footprint.v0) / rows;
  return {footprint.u0 + col * du, footprint.u0 + (col + 1) * du, footprint.v0 + row * dv,
          footprint.v0 + (row + 1) * dv};
}

GroundBox BlockGrid::margined(int block) const {
  GroundBox box = cell(block);
  const double mu = overlap * (box.u1 - box.u0), mv = overlap * (box.v1 - box.v0);
  return {box.u0 - mu, box.u1 + mu, box.v0 - mv, box.v1 + mv};
}

int BlockGrid::block_of(double u, double v) const {
  auto index = [](double x, double lo, double hi, int count) {
    const double f = (x - lo) / (hi - lo) * count;
    if (!(f > 0)) return 0;  // below the footprint, or NaN
    return std::min(count - 1, int(f));
  };
  return index(v, footprint.v0, footprint.v1, rows) * cols +
         index(u, footprint.u0, footprint.u1, cols);
}

double BlockGrid::blend_weight(int block, double u, double v, double blend) const {
  if (!(blend > 0) || !(overlap > 0)) return block_of(u, v) == block ? 1.0 : 0.0;
  // One axis: cell [lo, hi] of `count` cells, index i; the ramp's half-width h.
  auto ramp = [&](double x, double lo, double hi, int i, int count) {
    const double size = hi - lo, h = std::min(blend * overlap * size, 0.5 * size);
    if (!(h > 0)) return 1.0;
    double w = 1;
    if (i > 0) w = std::min(w, std::clamp(0.5 + (x - lo) / (2 * h), 0.0, 1.0));
    if (i < count - 1) w = std::min(w, std::clamp(0.5 + (hi - x) / (2 * h), 0.0, 1.0));
    return w;
  };
  const GroundBox c = cell(block);
  return ramp(u, c.u0, c.u1, block % cols, cols) * ramp(v, c.v0, c.v1, block / cols, rows);
}

std::string block_name(int block, int blocks) {
  const int width = std::max(2, int(std::to_string(std::max(0, blocks - 1)).size()));
  std::string digits = std::to_string(block);
  return "block_" + std::string(size_t(std::max(0, width - int(digits.size()))), '0') + digits;
}

namespace {

json vec(const core::Vec3& v) {
  return json::array({v.x, v.y, v.z});
}
json box(const GroundBox& b) {
  return {{"u", {b.u0, b.u1}}, {"v", {b.v0, b.v1}}};
}
json ground(const GroundFrame& f) {
  return {{"origin", vec(f.origin)}, {"u", vec(f.u)}, {"v", vec(f.v)}, {"normal", vec(f.n)}};
}

// Reads blocks.json with the file and key named in every refusal.
struct BlocksReader {
  fs::path path;
  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw core::Error(path, key + ": " + what);
  }
  const json& at(const json& parent, const std::string& key) const {
    if (!parent.is_object() || !parent.contains(key)) fail(key, "missing");
    return parent.at(key);
  }
  double number(const json& parent, const std::string& key) const {
    const json& v = at(parent, key);
    if (!v.is_number() || !std::isfinite(v.get<double>())) fail(key, "expected a finite number");
    return v.get<double>();
  }
  int integer(const json& parent, const std::string& key, int lo, int hi) const {
    const json& v = at(parent, key);
    if (!v.is_number_integer() || v.get<int64_t>() < lo || v.get<int64_t>() > hi)
      fail(key, "expected an integer from " + std::to_string(lo) + " to " + std::to_string(hi));
    return v.get<int>();
  }
  core::Vec3 vector(const json& parent, const std::string& key) const {
    const json& v = at(parent, key);
    if (!v.is_array() || v.size() != 3) fail(key, "expected 3 numbers");
    double x[3];
    for (size_t i = 0; i < 3; ++i) {
      if (!v[i].is_number() || !std::isfinite(v[i].get<double>()))
        fail(key, "expected 3 finite numbers");
      x[i] = v[i].get<double>();
    }
    return {x[0], x[1], x[2]};
  }
  std::pair<double, double> range(const json& parent, const std::string& key) const {
    const json& v = at(parent, key);
    if (!v.is_array() || v.size() != 2 || !v[0].is_number() || !v[1].is_number() ||
        !std::isfinite(v[0].get<double>()) || !std::isfinite(v[1].get<double>()) ||
        !(v[0].get<double>() < v[1].get<double>()))
      fail(key, "expected [low, high], low < high");
    return {v[0].get<double>(), v[1].get<double>()};
  }
  GroundFrame frame(const json& ground) const {
    GroundFrame f{vector(ground, "origin"), vector(ground, "u"), vector(ground, "v"),
                  vector(ground, "normal")};
    const core::Vec3 axes[3] = {f.u, f.v, f.n};
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b)
        if (std::abs(axes[a].dot(axes[b]) - (a == b ? 1 : 0)) > 1e-6)
          fail("ground", "u, v and normal must be orthonormal");
    return f;
  }
  GroundBox box(const json& b) const {
    GroundBox out;
    std::tie(out.u0, out.u1) = range(b, "u");
    std::tie(out.v0, out.v1) = range(b, "v");
    return out;
  }
  // The file's JSON object, when it is a `format` file of version 1 (`name`:
  // the key a file that is no JSON object is refused under).
  json object(const std::string& name, const std::string& format) const {
    require_regular_file(path);
    const json j = json::parse(read_file(path), nullptr, false);
    if (j.is_discarded() || !j.is_object()) fail(name, "not a JSON object");
    if (!j.contains("format") || j["format"] != format)
      fail("format", "expected \"" + format + "\" (a file written by ddhgs partition)");
    integer(j, "version", 1, 1);
    return j;
  }
  std::vector<std::string> strings(const json& parent, const std::string& key) const {
    const json& v = at(parent, key);
    if (!v.is_array()) fail(key, "expected a list of file paths");
    std::vector<std::string> out;
    for (const json& s : v) {
      if (!s.is_string()) fail(key, "expected a list of file paths");
      out.push_back(s.get<std::string>());
    }
    return out;
  }
};

}  // namespace

void write_blocks_file(const fs::path& path, const BlocksFile& file) {
  const BlockGrid& g = file.grid;
  json blocks = json::array();
  for (size_t i = 0; i < file.blocks.size(); ++i) {
    const BlockRecord& b = file.blocks[i];
    blocks.push_back({{"name", b.name},
                      {"row", b.row},
                      {"col", b.col},
                      {"cell", box(g.cell(int(i)))},
                      {"margined", box(g.margined(int(i)))},
                      {"train_views", b.train_views},
                      {"test_views", b.test_views},
                      {"points", b.points}});
  }
  json j = {{"format", "ddhgs blocks"},
            {"version", 1},
            {"scene", file.scene.string()},
            {"ground", ground(g.frame)},
            {"footprint", box(g.footprint)},
            {"rows", g.rows},
            {"cols", g.cols},
            {"overlap", g.overlap},
            {"blocks", blocks}};
  write_file_atomically(path, j.dump(2) + "\n");
}

BlocksFile read_blocks_file(const fs::path& path) {
  const BlocksReader r{path};
  const json j = r.object("blocks.json", "ddhgs blocks");
  BlocksFile file;
  const json& scene = r.at(j, "scene");
  if (!scene.is_string() || scene.get<std::string>().empty()) r.fail("scene", "expected a path");
  file.scene = scene.get<std::string>();
  BlockGrid& g = file.grid;
  g.frame = r.frame(r.at(j, "ground"));
  g.footprint = r.box(r.at(j, "footprint"));
  g.rows = r.integer(j, "rows", 1, 1000);
  g.cols = r.integer(j, "cols", 1, 1000);
  g.overlap = r.number(j, "overlap");
  if (g.overlap < 0 || g.overlap > 1) r.fail("overlap", "expected 0 to 1");
  const json& blocks = r.at(j, "blocks");
  if (!blocks.is_array() || int(blocks.size()) != g.blocks())
    r.fail("blocks", "expected rows x cols = " + std::to_string(g.blocks()) + " entries");
  for (const json& b : blocks) {
    BlockRecord record;
    const json& name = r.at(b, "name");
    if (!name.is_string()) r.fail("name", "expected a folder name");
    record.name = name.get<std::string>();
    const fs::path folder(record.name);
    if (record.name.empty() || folder.has_parent_path() || record.name == "." ||
        record.name == "..")
      r.fail("name", "expected a plain folder name, got '" + record.name + "'");
    record.row = r.integer(b, "row", 0, g.rows - 1);
    record.col = r.integer(b, "col", 0, g.cols - 1);
    if (record.row * g.cols + record.col != int(file.blocks.size()))
      r.fail("blocks", record.name + " is out of order (expected row-major order)");
    record.train_views = r.strings(b, "train_views");
    record.test_views = r.strings(b, "test_views");
    const json& points = r.at(b, "points");
    if (!points.is_number_integer() || points.get<int64_t>() < 0)
      r.fail("points", "expected a count");
    record.points = points.get<int64_t>();
    file.blocks.push_back(std::move(record));
  }
  return file;
}

void write_block_context(const fs::path& path, const BlockContext& c) {
  json j = {{"format", "ddhgs block"},
            {"version", 1},
            {"name", c.name},
            {"ground", ground(c.frame)},
            {"cell", box(c.cell)},
            {"margined", box(c.margined)},
            {"flight_train_views", c.flight_train_views},
            {"flight_extent", c.flight_extent}};
  if (!c.background.empty()) j["background"] = c.background;
  write_file_atomically(path, j.dump(2) + "\n");
}

std::optional<BlockContext> read_block_context(const fs::path& scene_root) {
  const fs::path path = scene_root / kBlockContextFile;
  if (!fs::exists(path)) return std::nullopt;
  const BlocksReader r{path};
  const json j = r.object(kBlockContextFile, "ddhgs block");
  BlockContext c;
  const json& name = r.at(j, "name");
  if (!name.is_string()) r.fail("name", "expected the block's folder name");
  c.name = name.get<std::string>();
  c.frame = r.frame(r.at(j, "ground"));
  c.cell = r.box(r.at(j, "cell"));
  c.margined = r.box(r.at(j, "margined"));
  c.flight_train_views = r.integer(j, "flight_train_views", 1, 1 << 30);
  c.flight_extent = r.number(j, "flight_extent");
  if (!(c.flight_extent > 0)) r.fail("flight_extent", "expected a positive number");
  if (j.contains("background")) {
    const json& bg = j.at("background");
    if (!bg.is_array() || bg.empty())
      r.fail("background", "expected a list of numbers, one per band");
    for (const json& value : bg) {
      if (!value.is_number() || !std::isfinite(value.get<double>()))
        r.fail("background", "expected a list of numbers, one per band");
      c.background.push_back(value.get<double>());
    }
  }
  return c;
}

}  // namespace ddhgs::io
