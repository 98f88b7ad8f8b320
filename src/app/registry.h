// Subcommand registry. Each cmd_*.cpp registers itself with a static
// Registrar, so adding a subcommand touches no shared file. Each keeps its
// code in a namespace named after its file (cmd_eval), not an anonymous one:
// the unity build compiles several commands as one source, where their
// `setup`, `run` and `registrar` would collide.
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

// A command-line value check: a finite number within [lo, hi]. CLI11's own
// Range and PositiveNumber let NaN through and have no upper bound, so a
// typo could run until killed (`--fps-repeats 1000000000`).
CLI::Validator within(double lo, double hi);

struct Registrar {
  Registrar(std::string name, int order, Setup setup) {
    registry().push_back({std::move(name), order, std::move(setup)});
  }
};

}  // namespace ddhgs::app
