// The ddhgs command line. Subcommands live one per file (cmd_*.cpp) and
// register themselves (app/registry.h).
#include <CLI/CLI.hpp>

#include <algorithm>
#include <iostream>

#include "app/registry.h"
#include "core/error.h"
#include "core/log.h"
#include "core/threads.h"

int main(int argc, char** argv) {
  using namespace ddhgs;
  CLI::App app{"ddhgs: hyperspectral Gaussian splatting (DD-HGS) on the CPU"};
  app.set_version_flag("--version", std::string(DDHGS_VERSION));
  app.require_subcommand(1);
  // Global options are accepted after the subcommand too (ddhgs train ... --threads 2).
  app.fallthrough();
  int threads = 0;
  bool quiet = false, verbose = false;
  app.add_option("--threads", threads, "Worker threads (default: $DDHGS_THREADS or all cores)");
  app.add_flag("-q,--quiet", quiet, "Only print warnings and errors");
  app.add_flag("-v,--verbose", verbose, "Print debugging details");

  auto& commands = app::registry();
  std::sort(commands.begin(), commands.end(),
            [](const app::Command& a, const app::Command& b) { return a.order < b.order; });
  std::vector<std::pair<CLI::App*, app::Action>> actions;
  for (auto& command : commands) {
    size_t before = app.get_subcommands({}).size();
    app::Action action = command.setup(app);
    auto subs = app.get_subcommands({});
    if (subs.size() > before) actions.emplace_back(subs.back(), std::move(action));
  }

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  core::set_log_level(quiet     ? core::LogLevel::Quiet
                      : verbose ? core::LogLevel::Verbose
                                : core::LogLevel::Normal);
  core::configure_threads(threads);
  try {
    for (auto& [sub, run] : actions)
      if (sub->parsed()) return run();
  } catch (const core::Error& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  } catch (const c10::Error& e) {
    std::cerr << "error: " << e.what_without_backtrace() << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
