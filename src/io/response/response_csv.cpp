#include "io/response/response_csv.h"

#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>

#include "core/error.h"

namespace ddhgs::io {
namespace {

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> cells;
  std::string cell;
  std::istringstream in(line);
  while (std::getline(in, cell, ',')) {
    const size_t first = cell.find_first_not_of(" \t\r"), last = cell.find_last_not_of(" \t\r");
    cells.push_back(first == std::string::npos ? "" : cell.substr(first, last - first + 1));
  }
  if (!line.empty() && line.back() == ',') cells.push_back("");
  return cells;
}

}  // namespace

core::ResponseFunctions read_response_csv(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in)
    throw core::Error(path,
                      std::filesystem::exists(path) ? "cannot open for reading" : "file not found");
  core::ResponseFunctions out;
  std::vector<double> values;
  std::string line;
  int line_number = 0;
  const std::string format = " (expected a header 'wavelength_nm,NAME,...' and rows of numbers)";
  while (std::getline(in, line)) {
    ++line_number;
    if (line.find_first_not_of(" \t\r") == std::string::npos || line[0] == '#') continue;
    const std::vector<std::string> cells = split(line);
    const std::string where = "line " + std::to_string(line_number) + ": ";
    if (out.channels.empty()) {
      if (cells.size() < 2) throw core::Error(path, where + "no channel columns" + format);
      for (size_t i = 1; i < cells.size(); ++i) {
        if (cells[i].empty())
          throw core::Error(path,
                            where + "column " + std::to_string(i + 1) + " has no name" + format);
        out.channels.push_back(cells[i]);
      }
      continue;
    }
    if (cells.size() != out.channels.size() + 1)
      throw core::Error(path, where + std::to_string(cells.size()) + " values; expected " +
                                  std::to_string(out.channels.size() + 1));
    for (size_t i = 0; i < cells.size(); ++i) {
      double value = 0;
      const std::string& cell = cells[i];
      auto [end, error] = std::from_chars(cell.data(), cell.data() + cell.size(), value);
      if (cell.empty() || error != std::errc() || end != cell.data() + cell.size() ||
          !std::isfinite(value))
        throw core::Error(path, where + "'" + cell + "' is not a number");
      if (i == 0) {
        if (!out.wavelengths_nm.empty() && value <= out.wavelengths_nm.back())
          throw core::Error(path, where + "wavelengths must increase");
        out.wavelengths_nm.push_back(value);
      } else {
        if (value < 0) throw core::Error(path, where + "a response below 0");
        values.push_back(value);
      }
    }
  }
  if (out.channels.empty() || out.wavelengths_nm.empty())
    throw core::Error(path, "no response rows" + format);
  out.values = torch::tensor(values, torch::kFloat64)
                   .reshape({int64_t(out.wavelengths_nm.size()), int64_t(out.channels.size())});
  return out;
}

}  // namespace ddhgs::io
