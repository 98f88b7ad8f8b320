#include "io/response/response_csv.h"

#include <charconv>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include "core/error.h"
#include "core/log.h"
#include "core/number_range.h"
#include "core/text.h"
#include "io/files/input_file.h"

namespace ddhgs::io {
namespace {

const char* const kFormat = " (expected a header 'wavelength_nm,NAME,...' and rows of numbers)";

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> cells;
  std::string cell;
  std::istringstream in(line);
  while (std::getline(in, cell, ',')) cells.push_back(core::trim(cell));
  if (!line.empty() && line.back() == ',') cells.push_back("");
  return cells;
}

// Whether the cell is one number, however large (from_chars answers
// result_out_of_range past a double's range, having read it whole).
bool parse_number(const std::string& cell, double* value) {
  const auto [end, error] = std::from_chars(cell.data(), cell.data() + cell.size(), *value);
  if (error == std::errc::result_out_of_range) *value = HUGE_VAL;
  return !cell.empty() && (error == std::errc() || error == std::errc::result_out_of_range) &&
         end == cell.data() + cell.size();
}

// The channel names of the header row; a row of numbers is no header.
std::vector<std::string> channel_names(const std::vector<std::string>& cells,
                                       const std::filesystem::path& path,
                                       const std::string& where) {
  double number = 0;
  if (parse_number(cells[0], &number))
    throw core::Error(path, where + "starts with the number " + core::quoted_value(cells[0]) +
                                ", not a header; the first row names the columns" + kFormat);
  if (cells.size() < 2) throw core::Error(path, where + "no channel columns" + kFormat);
  std::vector<std::string> names;
  std::set<std::string> seen;
  for (size_t i = 1; i < cells.size(); ++i) {
    const std::string column = "column " + std::to_string(i + 1);
    if (cells[i].empty()) throw core::Error(path, where + column + " has no name" + kFormat);
    // Names go into logs and messages whole: short, printable.
    if (cells[i].size() > core::kQuotedChars)
      throw core::Error(path, where + column + "'s name " + core::quoted_value(cells[i]) +
                                  " is longer than " + std::to_string(core::kQuotedChars) +
                                  " characters");
    if (core::printable(cells[i]) != cells[i])
      throw core::Error(path, where + column + "'s name " + core::quoted_value(cells[i]) +
                                  " holds a control character");
    if (!seen.insert(cells[i]).second)
      throw core::Error(path, where + column + " repeats the name " + core::quoted_value(cells[i]));
    names.push_back(cells[i]);
  }
  return names;
}

}  // namespace

core::ResponseFunctions read_response_csv(const std::filesystem::path& path) {
  require_regular_file(path);
  std::ifstream in(path);
  if (!in) throw core::Error(path, "cannot open for reading");
  core::ResponseFunctions out;
  std::vector<double> values;
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (line.find_first_not_of(" \t\r") == std::string::npos || line[0] == '#') continue;
    const std::vector<std::string> cells = split(line);
    const std::string where = "line " + std::to_string(line_number) + ": ";
    if (out.channels.empty()) {
      out.channels = channel_names(cells, path, where);
      continue;
    }
    if (cells.size() != out.channels.size() + 1)
      throw core::Error(path, where + std::to_string(cells.size()) + " values; expected " +
                                  std::to_string(out.channels.size() + 1));
    for (size_t i = 0; i < cells.size(); ++i) {
      double value = 0;
      const std::string& cell = cells[i];
      const std::string column =
          " (column " + (i == 0 ? "wavelength_nm" : core::quoted_value(out.channels[i - 1])) + ")";
      if (!parse_number(cell, &value) || std::isnan(value))
        throw core::Error(path, where + core::quoted_value(cell) + " is not a number" + column);
      if (!core::renderable_number(value))
        throw core::Error(path, where + core::quoted_value(cell) + " is out of range (at most " +
                                    core::format_g(core::kMaxFileNumber) + " in magnitude)" +
                                    column);
      if (i == 0) {
        if (!(value > 0))
          throw core::Error(
              path, where + "wavelength " + core::quoted_value(cell) + " nm is not above 0");
        if (!out.wavelengths_nm.empty() && value <= out.wavelengths_nm.back())
          throw core::Error(path, where + "wavelengths must increase");
        out.wavelengths_nm.push_back(value);
      } else {
        if (value < 0) throw core::Error(path, where + "a response below 0" + column);
        values.push_back(value);
      }
    }
  }
  if (out.channels.empty() || out.wavelengths_nm.empty())
    throw core::Error(path, "no response rows" + std::string(kFormat));
  out.values = torch::tensor(values, torch::kFloat64)
                   .reshape({int64_t(out.wavelengths_nm.size()), int64_t(out.channels.size())});
  return out;
}

}  // namespace ddhgs::io
