#include "core/text.h"

#include <cctype>
#include <cstdio>

namespace ddhgs::core {

std::string lower(std::string s) {
  for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string trim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t\r\n");
  if (a == std::string::npos) return {};
  const size_t b = s.find_last_not_of(" \t\r\n");
  return s.substr(a, b - a + 1);
}

std::string join_numbers(const std::vector<double>& values) {
  std::string out;
  char item[32];
  for (size_t i = 0; i < values.size(); ++i) {
    std::snprintf(item, sizeof item, "%s%.17g", i ? "," : "", values[i]);
    out += item;
  }
  return out;
}

}  // namespace ddhgs::core
