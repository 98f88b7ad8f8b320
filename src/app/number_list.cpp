#include "app/number_list.h"

#include <cmath>
#include <sstream>

#include "core/error.h"
#include "core/text.h"

namespace ddhgs::app {

std::vector<double> parse_number_list(const std::string& text, const std::string& option) {
  std::vector<double> values;
  std::stringstream items(text);
  for (std::string item; std::getline(items, item, ',');) {
    size_t used = 0;
    double value = 0;
    try {
      value = std::stod(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || item.find_first_not_of(' ', used) != std::string::npos ||
        !std::isfinite(value))
      throw core::Error(option + ": " + core::quoted_value(item) + " is not a number");
    values.push_back(value);
  }
  return values;
}

}  // namespace ddhgs::app
