#include "app/registry.h"

#include <cmath>
#include <sstream>

namespace ddhgs::app {

std::vector<Command>& registry() {
  static std::vector<Command> commands;
  return commands;
}

namespace {

std::string number_text(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

}  // namespace

CLI::Validator within(double lo, double hi) {
  const std::string range = "[" + number_text(lo) + " - " + number_text(hi) + "]";
  return CLI::Validator(
      [lo, hi, range](std::string& text) -> std::string {
        double value = 0;
        std::istringstream in(text);
        in >> value;
        if (in.fail() || !(in >> std::ws).eof())
          return "'" + text + "' is not a number";  // CLI11 converts after checks
        if (!std::isfinite(value) || value < lo || value > hi)
          return "is " + text + ", expected a value in " + range;
        return "";
      },
      range);
}

}  // namespace ddhgs::app
