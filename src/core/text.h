// Small text helpers shared by the file readers and error messages.
#pragma once
#include <string>
#include <string_view>
#include <vector>

namespace ddhgs::core {

// ASCII lower case ("TIF" -> "tif"), e.g. of a file extension.
std::string lower(std::string s);

// Without leading and trailing spaces, tabs, CRs and LFs (XML's and header
// files' whitespace).
std::string trim(const std::string& s);

// "0.5,-0.25,3": comma-separated, each to 17 significant digits (a double
// reads back exactly), as metadata lists and COLMAP options write them.
std::string join_numbers(const std::vector<double>& values);

// value with `decimals` digits after the point ("%.*f": fixed(2.345, 2) is "2.35").
std::string fixed(double value, int decimals);

// value to 6 significant digits ("%.6g": 0.000123457, 1449.36, 1e+300), as
// messages quote a file's number.
std::string number_text(double value);

// The characters of a user's value a message quotes (quoted_value()).
constexpr size_t kQuotedChars = 80;

// A user's value for a message, in single quotes: control characters as
// escapes ("\0", "\t", "\x1b"; a NUL would end the message where it is
// printed) and, past kQuotedChars characters, the rest left out and counted:
// 'aaaa...' (and 52428720 more characters).
std::string quoted_value(std::string_view value);

// text with its control characters as escapes (as quoted_value(), without quotes
// or clipping).
std::string printable(std::string_view text);

}  // namespace ddhgs::core
