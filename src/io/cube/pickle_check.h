// The guard in front of LibTorch's unpickler (private to io/cube).
#pragma once
#include <cstddef>
#include <filesystem>

namespace ddhgs::io::detail {

// LibTorch 1.13's unpickler trusts the pickle of a torch.save file: it
// allocates a string's declared length before reading it (4 GB from one
// corrupt length field), and opcodes that find too few values on its stack,
// or a mark above it, read outside the stack (a segfault). Walks the pickle
// as the unpickler will, counting its stack and marks, and throws
// core::Error naming `path` where either would happen. The walk ends at STOP
// and at the first opcode the unpickler does not know (it refuses those).
// pickle: the data.pkl record of the archive, `size` bytes.
void check_pickle(const char* pickle, size_t size, const std::filesystem::path& path);

}  // namespace ddhgs::io::detail
