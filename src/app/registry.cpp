#include "app/registry.h"

namespace ddhgs::app {

std::vector<Command>& registry() {
  static std::vector<Command> commands;
  return commands;
}

}  // namespace ddhgs::app
