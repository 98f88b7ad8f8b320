// Single output files named on the command line (render-ply --out and
// --preview, export --out): checked before any work, so that a typo can
// neither overwrite an input nor leave a PNG named .npy.
#pragma once
#include <filesystem>
#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

namespace ddhgs::io {

// core::Error naming flag unless path ends in one of extensions (".npy";
// compared without regard to case).
void require_extension(const std::filesystem::path& path, const std::string& flag,
                       std::initializer_list<const char*> extensions);

// True when a and b name the same file: the same inode when both exist, the
// same normalised absolute path otherwise.
bool same_file(const std::filesystem::path& a, const std::filesystem::path& b);

// core::Error naming flag when path is one of the others (what each is
// called, e.g. {"the input PLY", ply}): an output must not replace an input
// or another output of the same command.
void require_distinct(const std::filesystem::path& path, const std::string& flag,
                      const std::vector<std::pair<std::string, std::filesystem::path>>& others);

}  // namespace ddhgs::io
