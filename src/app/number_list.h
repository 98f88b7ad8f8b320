// Comma-separated numbers given to a command-line option ("0.2,0.3,0.1").
#pragma once
#include <string>
#include <vector>

namespace ddhgs::app {

// Every item must be a finite number (spaces around it allowed); core::Error
// naming the option and the item otherwise.
std::vector<double> parse_number_list(const std::string& text, const std::string& option);

}  // namespace ddhgs::app
