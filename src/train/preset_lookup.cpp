#include "train/preset_lookup.h"

#include <cstdlib>

#include "core/error.h"
#include "core/log.h"
#include "io/files/atomic_file.h"

namespace ddhgs::train {

namespace fs = std::filesystem;

std::vector<fs::path> preset_folders() {
  std::vector<fs::path> folders;
  if (const char* env = std::getenv("DDHGS_CONFIG_DIR"); env && *env) folders.emplace_back(env);
  std::error_code ec;
  const fs::path program = fs::read_symlink("/proc/self/exe", ec);
  if (ec) return folders;
  const fs::path dir = program.parent_path();
  folders.push_back(dir / "configs");
  folders.push_back((dir / ".." / "share" / "ddhgs" / "configs").lexically_normal());
  folders.push_back((dir / ".." / "configs").lexically_normal());
  return folders;
}

PresetText read_preset_file(const fs::path& path) {
  if (!fs::exists(path)) throw core::Error(path, "no such preset");
  return {path.string(), io::read_file(path), path.parent_path()};
}

PresetText find_preset(const std::string& name) {
  const std::string file = name + ".json";
  const std::vector<fs::path> folders = preset_folders();
  for (const fs::path& folder : folders)
    if (fs::exists(folder / file)) {
      core::log_debug("preset " + name + ": " + (folder / file).string());
      return read_preset_file(folder / file);
    }
  std::string built_in;
  for (const BuiltinPreset& preset : builtin_presets()) {
    if (preset.name == name) {
      core::log_debug("preset " + name + ": built in (" + preset.source + ")");
      return {preset.source + " (built in)", preset.contents, {}};
    }
    built_in += (built_in.empty() ? "" : ", ") + preset.name;
  }
  std::string looked;
  for (const fs::path& folder : folders) looked += folder.string() + ", ";
  if (!looked.empty()) looked = "looked for " + file + " in " + looked + "then ";
  throw core::Error("no such preset '" + name + "': " + looked +
                    "among the presets built into ddhgs (" + built_in + ")");
}

}  // namespace ddhgs::train
