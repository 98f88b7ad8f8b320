// Where a preset comes from. A name ("demo") is looked up, in order, in
//   $DDHGS_CONFIG_DIR, when set;
//   configs/ beside the program (a binary copied with its presets);
//   ../share/ddhgs/configs from the program's folder (an install prefix P:
//     P/bin/ddhgs and P/share/ddhgs/configs, as `cmake --install` lays them out);
//   ../configs from the program's folder (build/ddhgs in the source tree);
// and last among the presets built into the program (configs/*.json as they
// were when it was built), so that a binary copied anywhere still trains. A
// path to a .json file is read as given.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

namespace ddhgs::train {

// A preset's JSON text and where it came from.
struct PresetText {
  std::string source;  // the file, or "configs/demo.json (built in)": names it in errors
  std::string text;    // the JSON
  std::filesystem::path directory;  // what an "extends" path is relative to (empty when built in)
};

// The folders searched for a preset by name, in order, before the built-in ones.
std::vector<std::filesystem::path> preset_folders();

// The preset `name` (without ".json"). core::Error naming every place looked
// in when none holds it.
PresetText find_preset(const std::string& name);

// A preset file by its path. core::Error when it does not exist.
PresetText read_preset_file(const std::filesystem::path& path);

// configs/*.json as they were when the program was built (generated from
// them by cmake/embed.cmake), in file-name order.
struct BuiltinPreset {
  std::string name;      // "demo"
  std::string source;    // "configs/demo.json"
  std::string contents;  // the JSON text
};
const std::vector<BuiltinPreset>& builtin_presets();

}  // namespace ddhgs::train
