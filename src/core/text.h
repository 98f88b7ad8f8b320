// Small text helpers shared by the file readers.
#pragma once
#include <string>

namespace ddhgs::core {

// ASCII lower case ("TIF" -> "tif"), e.g. of a file extension.
std::string lower(std::string s);

// Without leading and trailing spaces, tabs, CRs and LFs (XML's and header
// files' whitespace).
std::string trim(const std::string& s);

}  // namespace ddhgs::core
