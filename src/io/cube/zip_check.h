// The guard in front of LibTorch's zip reader (private to io/cube).
#pragma once
#include <filesystem>

namespace ddhgs::io::detail {

// LibTorch's PyTorchStreamReader::getRecord allocates the size a record's
// central directory entry declares before it extracts the record: two
// changed fields (deflated, 4 GB) make a 1 kB file allocate 4 GB and read
// the uninitialised memory as the record. Reads the central directory the
// way miniz (LibTorch's zip library) finds it and throws core::Error naming
// the file when a record declares more than the file can hold: a stored
// record more than the file's size, a compressed one more than the largest
// plausible expansion of it (io/files/byte_count.h). Call it before the
// archive is opened: PyTorchStreamReader's constructor already extracts the
// version record. Every read here is clamped to the file and every entry
// advances past the last, so any file is safe to check; one miniz would
// refuse passes unchecked and is refused by miniz.
void check_zip_record_sizes(const std::filesystem::path& path);

}  // namespace ddhgs::io::detail
