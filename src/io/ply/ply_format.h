// The PLY container: header parsing and streaming of one element's
// properties into caller-owned columns, for ASCII and binary files. Used by
// io/ply.cpp; knows nothing of Gaussians or point clouds.
#pragma once
#include <cstdint>
#include <filesystem>
#include <istream>
#include <string>
#include <utility>
#include <vector>

namespace ddhgs::io::ply {

enum class Format { Ascii, BinaryLittleEndian, BinaryBigEndian };
enum class Type : uint8_t { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

size_t type_size(Type type);
const char* type_name(Type type);  // "float", "uchar", ...

struct Property {
  std::string name;
  Type type = Type::Float32;  // item type for lists
  bool is_list = false;
  Type count_type = Type::UInt8;
};

struct Element {
  std::string name;
  int64_t count = 0;
  std::vector<Property> properties;

  int find(const std::string& property) const;  // index, or -1 when absent
};

struct Header {
  Format format = Format::BinaryLittleEndian;
  std::vector<Element> elements;
  std::vector<std::string> comments;  // text after "comment "
  int64_t data_offset = 0;            // bytes from the file start to the first element

  int find(const std::string& element) const;  // index, or -1 when absent
};

// Reads the header from the start of `in` (opened in binary mode). Throws
// core::Error naming path on a missing magic, unknown format or type, or a
// header without end_header.
Header read_header(std::istream& in, const std::filesystem::path& path);

// Destination of one property: values land at f32[i * stride] (or u8[...])
// for entry i of the element. Float values must be finite; values stored
// into u8 are rounded and clamped to 0-255.
struct Column {
  int property = -1;
  float* f32 = nullptr;
  uint8_t* u8 = nullptr;
  int64_t stride = 1;
};

// Checks, before anything is allocated, that the file is long enough for the
// declared entry counts up to and including `element` (exact for binary
// files, at least two bytes per value for ASCII). Throws core::Error naming
// path when it is not.
void check_file_size(const std::filesystem::path& path, const Header& header, int element);

// Streams element `element` of the file into columns; other properties are
// skipped. Checks before allocating or reading that the file is long enough.
// Throws core::Error naming path on truncation, bad ASCII numbers, non-finite
// floats, or list properties inside the element read.
void read_element(std::istream& in, const std::filesystem::path& path, const Header& header,
                  int element, const std::vector<Column>& columns);

// Header of a binary little-endian file with a single element.
std::string binary_header(const std::vector<std::string>& comments, const std::string& element,
                          int64_t count,
                          const std::vector<std::pair<std::string, Type>>& properties);

}  // namespace ddhgs::io::ply
