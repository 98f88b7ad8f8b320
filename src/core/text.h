// Small text helpers shared by the file readers.
#pragma once
#include <string>
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

}  // namespace ddhgs::core
