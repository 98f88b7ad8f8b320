#include "core/text.h"

#include <cctype>
#include <cstdio>
#include <string>

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

std::string printable(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte >= 0x20 && byte != 0x7f) {
      out += c;
      continue;
    }
    switch (c) {
      case '\0':
        out += "\\0";
        break;
      case '\t':
        out += "\\t";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\r':
        out += "\\r";
        break;
      default: {
        char escape[8];
        std::snprintf(escape, sizeof escape, "\\x%02x", unsigned(byte));
        out += escape;
      }
    }
  }
  return out;
}

std::string fixed(double value, int decimals) {
  char text[64];
  std::snprintf(text, sizeof text, "%.*f", decimals, value);
  return text;
}

std::string number_text(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6g", value);
  return text;
}

std::string quoted_value(std::string_view value) {
  if (value.size() <= kQuotedChars) return "'" + printable(value) + "'";
  size_t kept = kQuotedChars;
  // Not inside a UTF-8 sequence: back over its continuation bytes.
  while (kept > 0 && (static_cast<unsigned char>(value[kept]) & 0xC0) == 0x80) --kept;
  return "'" + printable(value.substr(0, kept)) + "...' (and " +
         std::to_string(value.size() - kept) + " more characters)";
}

}  // namespace ddhgs::core
