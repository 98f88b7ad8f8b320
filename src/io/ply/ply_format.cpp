#include "io/ply/ply_format.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <sstream>

#include "core/error.h"

namespace ddhgs::io::ply {
namespace fs = std::filesystem;

namespace {

// A header longer than this is garbage, not a PLY (ours with 256 bands x 16
// coefficients is about 100 kB).
constexpr int64_t kMaxHeaderBytes = 64 << 20;

struct TypeInfo {
  Type type;
  size_t size;
  const char* names[2];  // classic and sized spelling
};
constexpr TypeInfo kTypes[] = {
    {Type::Int8, 1, {"char", "int8"}},        {Type::UInt8, 1, {"uchar", "uint8"}},
    {Type::Int16, 2, {"short", "int16"}},     {Type::UInt16, 2, {"ushort", "uint16"}},
    {Type::Int32, 4, {"int", "int32"}},       {Type::UInt32, 4, {"uint", "uint32"}},
    {Type::Float32, 4, {"float", "float32"}}, {Type::Float64, 8, {"double", "float64"}},
};

bool parse_type(const std::string& name, Type* type) {
  for (const auto& info : kTypes)
    if (name == info.names[0] || name == info.names[1]) {
      *type = info.type;
      return true;
    }
  return false;
}

template <typename T>
double load(const char* p, bool swap) {
  char bytes[sizeof(T)];
  if (swap)
    std::reverse_copy(p, p + sizeof(T), bytes);
  else
    std::memcpy(bytes, p, sizeof(T));
  T value;
  std::memcpy(&value, bytes, sizeof(T));
  return double(value);
}

double decode(const char* p, Type type, bool swap) {
  switch (type) {
    case Type::Int8:
      return load<int8_t>(p, swap);
    case Type::UInt8:
      return load<uint8_t>(p, swap);
    case Type::Int16:
      return load<int16_t>(p, swap);
    case Type::UInt16:
      return load<uint16_t>(p, swap);
    case Type::Int32:
      return load<int32_t>(p, swap);
    case Type::UInt32:
      return load<uint32_t>(p, swap);
    case Type::Float32:
      return load<float>(p, swap);
    case Type::Float64:
      return load<double>(p, swap);
  }
  return 0;
}

// Writes one value to its column, with the file, property and entry named in errors.
struct Sink {
  const fs::path& path;
  const Element& element;

  void store(const Column& column, int64_t entry, double value) const {
    const bool finite = column.f32 ? std::isfinite(float(value)) : std::isfinite(value);
    if (!finite)
      throw core::Error(path, "property '" + element.properties[column.property].name + "' of " +
                                  element.name + " " + std::to_string(entry) +
                                  " is not a finite number");
    if (column.f32)
      column.f32[entry * column.stride] = float(value);
    else
      column.u8[entry * column.stride] = uint8_t(std::clamp(std::round(value), 0.0, 255.0));
  }
};

void check_stream(const std::istream& in, const fs::path& path, const Element& element,
                  int64_t entry) {
  if (!in)
    throw core::Error(path, "file ends inside " + element.name + " " + std::to_string(entry) +
                                " of " + std::to_string(element.count) + " (truncated?)");
}

void skip_element(std::istream& in, const fs::path& path, const Header& header,
                  const Element& element) {
  if (header.format == Format::Ascii) {
    std::string line;
    for (int64_t i = 0; i < element.count; ++i) {
      std::getline(in, line);
      check_stream(in, path, element, i);
    }
    return;
  }
  const bool swap = header.format == Format::BinaryBigEndian;
  for (int64_t i = 0; i < element.count; ++i) {
    for (const auto& property : element.properties) {
      int64_t bytes = int64_t(type_size(property.type));
      if (property.is_list) {
        char count[8];
        in.read(count, std::streamsize(type_size(property.count_type)));
        check_stream(in, path, element, i);
        double n = decode(count, property.count_type, swap);
        if (n < 0) throw core::Error(path, "negative list length in element " + element.name);
        bytes *= int64_t(n);
      }
      in.seekg(bytes, std::ios::cur);
    }
    check_stream(in, path, element, i);
  }
}

void read_binary(std::istream& in, const fs::path& path, const Header& header,
                 const Element& element, const std::vector<Column>& columns) {
  std::vector<int64_t> offsets;
  int64_t record = 0;
  for (const auto& property : element.properties) {
    offsets.push_back(record);
    record += int64_t(type_size(property.type));
  }
  const int64_t start = int64_t(in.tellg());
  const int64_t available = int64_t(fs::file_size(path)) - start;
  if (record > 0 && element.count > available / record)
    throw core::Error(path, "element '" + element.name + "' declares " +
                                std::to_string(element.count) + " entries of " +
                                std::to_string(record) + " bytes but only " +
                                std::to_string(available) + " bytes follow (truncated?)");
  const bool swap = header.format == Format::BinaryBigEndian;
  const Sink sink{path, element};
  const int64_t chunk = std::max<int64_t>(1, (int64_t(1) << 22) / std::max<int64_t>(record, 1));
  std::vector<char> buffer(size_t(std::min(chunk, element.count) * record));
  for (int64_t first = 0; first < element.count; first += chunk) {
    const int64_t n = std::min(chunk, element.count - first);
    in.read(buffer.data(), std::streamsize(n * record));
    check_stream(in, path, element, first);
    for (const auto& column : columns) {
      const Type type = element.properties[column.property].type;
      const char* p = buffer.data() + offsets[column.property];
      for (int64_t i = 0; i < n; ++i)
        sink.store(column, first + i, decode(p + i * record, type, swap));
    }
  }
}

void read_ascii(std::istream& in, const fs::path& path, const Element& element,
                const std::vector<Column>& columns) {
  const Sink sink{path, element};
  const size_t expected = element.properties.size();
  std::vector<double> values(expected);
  std::string line;
  for (int64_t entry = 0; entry < element.count; ++entry) {
    do {
      std::getline(in, line);
      check_stream(in, path, element, entry);
    } while (line.find_first_not_of(" \t\r") == std::string::npos);
    const char* p = line.c_str();
    size_t n = 0;
    while (true) {
      while (*p == ' ' || *p == '\t' || *p == '\r') ++p;
      if (!*p) break;
      char* end = nullptr;
      double value = std::strtod(p, &end);
      if (end == p || (*end && *end != ' ' && *end != '\t' && *end != '\r'))
        throw core::Error(path, element.name + " " + std::to_string(entry) +
                                    ": not a number in line '" + line + "'");
      if (n < expected) values[n] = value;
      ++n;
      p = end;
    }
    if (n != expected)
      throw core::Error(path, element.name + " " + std::to_string(entry) + " has " +
                                  std::to_string(n) + " values, expected " +
                                  std::to_string(expected));
    for (const auto& column : columns) sink.store(column, entry, values[column.property]);
  }
}

}  // namespace

size_t type_size(Type type) {
  return kTypes[int(type)].size;
}

const char* type_name(Type type) {
  return kTypes[int(type)].names[0];
}

int Element::find(const std::string& property) const {
  for (size_t i = 0; i < properties.size(); ++i)
    if (properties[i].name == property) return int(i);
  return -1;
}

int Header::find(const std::string& element) const {
  for (size_t i = 0; i < elements.size(); ++i)
    if (elements[i].name == element) return int(i);
  return -1;
}

Header read_header(std::istream& in, const fs::path& path) {
  auto next_line = [&](std::string& line) {
    if (!std::getline(in, line)) return false;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return true;
  };
  std::string line;
  if (!next_line(line) || line != "ply")
    throw core::Error(path, "not a PLY file (it does not start with 'ply')");
  Header header;
  bool have_format = false;
  while (true) {
    if (!next_line(line)) throw core::Error(path, "PLY header has no end_header line (truncated?)");
    if (int64_t(in.tellg()) > kMaxHeaderBytes)
      throw core::Error(path, "PLY header is longer than 64 MB; not a PLY file?");
    std::istringstream words(line);
    std::string keyword;
    words >> keyword;
    auto bad = [&](const std::string& what) {
      return core::Error(path, what + " in PLY header line '" + line + "'");
    };
    if (keyword == "end_header") break;
    if (keyword.empty() || keyword == "obj_info") continue;
    if (keyword == "comment") {
      header.comments.push_back(line.size() > 8 ? line.substr(8) : "");
    } else if (keyword == "format") {
      std::string format, version;
      words >> format >> version;
      if (format == "ascii")
        header.format = Format::Ascii;
      else if (format == "binary_little_endian")
        header.format = Format::BinaryLittleEndian;
      else if (format == "binary_big_endian")
        header.format = Format::BinaryBigEndian;
      else
        throw bad("unknown format '" + format + "'");
      have_format = true;
    } else if (keyword == "element") {
      Element element;
      if (!(words >> element.name >> element.count) || element.count < 0)
        throw bad("expected 'element NAME COUNT'");
      header.elements.push_back(element);
    } else if (keyword == "property") {
      if (header.elements.empty()) throw bad("property before any element");
      Property property;
      std::string type;
      words >> type;
      if (type == "list") {
        std::string count_type;
        words >> count_type >> type;
        property.is_list = true;
        if (!parse_type(count_type, &property.count_type) || property.count_type == Type::Float32 ||
            property.count_type == Type::Float64)
          throw bad("list count type '" + count_type + "' is not an integer type");
      }
      if (!parse_type(type, &property.type)) throw bad("unknown type '" + type + "'");
      if (!(words >> property.name)) throw bad("property without a name");
      Element& element = header.elements.back();
      if (element.find(property.name) >= 0) throw bad("duplicate property");
      element.properties.push_back(property);
    } else {
      throw bad("unknown keyword '" + keyword + "'");
    }
  }
  if (!have_format) throw core::Error(path, "PLY header has no format line");
  header.data_offset = int64_t(in.tellg());
  return header;
}

void check_file_size(const fs::path& path, const Header& header, int element) {
  const int64_t available = int64_t(fs::file_size(path)) - header.data_offset;
  int64_t needed = 0;  // bytes, a lower bound when lists are present
  for (int i = 0; i <= element; ++i) {
    const Element& e = header.elements[size_t(i)];
    int64_t record = 0;
    for (const auto& property : e.properties)
      record += header.format == Format::Ascii ? 2
                : property.is_list             ? int64_t(type_size(property.count_type))
                                               : int64_t(type_size(property.type));
    if (record > 0 && e.count > (available - needed) / record)
      throw core::Error(path, "element '" + e.name + "' declares " + std::to_string(e.count) +
                                  " entries but the file is only " + std::to_string(available) +
                                  " bytes long after its header (truncated?)");
    needed += e.count * record;
  }
}

void read_element(std::istream& in, const fs::path& path, const Header& header, int element,
                  const std::vector<Column>& columns) {
  in.seekg(header.data_offset);
  for (int i = 0; i < element; ++i) skip_element(in, path, header, header.elements[i]);
  const Element& target = header.elements[element];
  for (const auto& property : target.properties)
    if (property.is_list)
      throw core::Error(path, "list property '" + property.name + "' in element '" + target.name +
                                  "' is not supported");
  if (header.format == Format::Ascii)
    read_ascii(in, path, target, columns);
  else
    read_binary(in, path, header, target, columns);
}

std::string binary_header(const std::vector<std::string>& comments, const std::string& element,
                          int64_t count,
                          const std::vector<std::pair<std::string, Type>>& properties) {
  std::string out = "ply\nformat binary_little_endian 1.0\n";
  for (const auto& comment : comments) out += "comment " + comment + "\n";
  out += "element " + element + " " + std::to_string(count) + "\n";
  for (const auto& [name, type] : properties)
    out += std::string("property ") + type_name(type) + " " + name + "\n";
  return out + "end_header\n";
}

}  // namespace ddhgs::io::ply
