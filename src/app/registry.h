// Subcommand registry. Each cmd_*.cpp registers itself with a static
// Registrar, so adding a subcommand touches no shared file.
#pragma once
#include <CLI/CLI.hpp>

#include <functional>
#include <string>
#include <vector>

namespace ddhgs::app {

// What a subcommand runs once parsed; returns the process exit code.
using Action = std::function<int()>;
// Adds the subcommand (and its options) to the parent app; returns its action.
using Setup = std::function<Action(CLI::App& parent)>;

struct Command {
  std::string name;
  int order;  // position in --help
  Setup setup;
};

std::vector<Command>& registry();

struct Registrar {
  Registrar(std::string name, int order, Setup setup) {
    registry().push_back({std::move(name), order, std::move(setup)});
  }
};

}  // namespace ddhgs::app
