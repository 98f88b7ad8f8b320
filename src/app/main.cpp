// The ddhgs command line. Subcommands live one per file (cmd_*.cpp) and
// register themselves (app/registry.h).
#include <CLI/CLI.hpp>

#include <algorithm>
#include <iostream>
#include <new>
#include <string>

#include "app/build_info.h"
#include "app/registry.h"
#include "core/early_setup.h"
#include "core/error.h"
#include "core/log.h"
#include "core/text.h"
#include "core/threads.h"

namespace {

// A LibTorch error that escaped every reader's own check, as one line: its
// first line without the "[enforce fail at alloc_cpu.cpp:75] err == 0. "
// location tag, and an allocation failure said as such.
std::string torch_error_text(const c10::Error& e) {
  std::string text = e.what_without_backtrace();
  text = text.substr(0, text.find('\n'));
  if (text.rfind("[enforce fail at ", 0) == 0 && text.find("] ") != std::string::npos)
    text = text.substr(text.find("] ") + 2);
  const size_t tried = text.find("you tried to allocate");
  if (tried != std::string::npos)
    return "out of memory: " + text.substr(tried, text.find('.', tried) - tried) +
           " (is a size in the input, or a flag, far too large?)";
  return text;
}

// CLI11's message with every word it quotes from the command line (a
// 50 MB number, a NUL) as core::quoted_value() would show it: at most
// core::kQuotedChars characters of each.
std::string clipped_parse_error(const std::string& text) {
  std::string out;
  size_t at = 0;
  while (at < text.size()) {
    const size_t space = std::min(text.find(' ', at), text.size());
    const std::string_view word(text.data() + at, space - at);
    out += word.size() > ddhgs::core::kQuotedChars ? ddhgs::core::quoted_value(word)
                                                   : ddhgs::core::printable(word);
    if (space < text.size()) out += ' ';
    at = space + 1;
  }
  return out;
}

// An empty value is never meant: `--wavelengths ''` would otherwise render
// the plain bands, `--index ''` no index. The first option of the parsed
// subcommand given one, or null.
const CLI::Option* option_with_empty_value(const CLI::App& command) {
  for (const CLI::Option* option : command.get_options()) {
    const bool flag = option->get_type_size_max() == 0 || option->get_expected_min() == 0;
    if (flag || option->count() == 0) continue;
    for (const std::string& value : option->results())
      if (value.find_first_not_of(" \t") == std::string::npos) return option;
  }
  return nullptr;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace ddhgs;
  CLI::App app{"ddhgs: hyperspectral Gaussian splatting (DD-HGS) on the CPU"};
  app.set_version_flag("--version",
                       std::string("ddhgs ") + DDHGS_VERSION + ", commit " + app::build_commit());
  app.require_subcommand(1);
  // Global options are accepted after the subcommand too (ddhgs train ... --threads 2).
  app.fallthrough();
  int threads = 0;
  bool quiet = false, verbose = false;
  app.add_option("--threads", threads,
                 "Worker threads (default: $DDHGS_THREADS, else the CPUs this process may use: its "
                 "affinity mask and cgroup CPU quota; at most 4 per CPU)");
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
    // --help and --version print and succeed; anything else is one error
    // line and exit 1, like every other error (not CLI11's two lines and
    // its own exit codes 104-109).
    if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) return app.exit(e);
    std::string text = e.what();
    std::replace(text.begin(), text.end(), '\n', ' ');
    std::cerr << "error: " << clipped_parse_error(text) << " (see --help)\n";
    return 1;
  }
  for (auto& [sub, run] : actions)
    if (sub->parsed())
      if (const CLI::Option* option = option_with_empty_value(*sub)) {
        std::cerr << "error: " << option->get_name() << ": an empty value"
                  << (option->get_positional() ? "" : " (give one, or leave the option out)")
                  << "\n";
        return 1;
      }
  core::set_log_level(quiet     ? core::LogLevel::Quiet
                      : verbose ? core::LogLevel::Verbose
                                : core::LogLevel::Normal);
  // Checked here, not by CLI11, whose range message spells out DBL_MAX.
  if (threads < 0) {
    std::cerr << "error: --threads: is " << threads << ", expected >= 0 (0: all cores)\n";
    return 1;
  }
  core::configure_threads(threads);
  core::log_debug(core::thread_summary());
  try {
    for (auto& [sub, run] : actions)
      if (sub->parsed()) return run();
  } catch (const core::Error& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  } catch (const c10::Error& e) {
    std::cerr << "error: " << torch_error_text(e) << "\n";
    return 1;
  } catch (const std::bad_alloc&) {
    std::cerr << "error: out of memory (is a size in the input, or a flag, far too large?)\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "error: " << core::message_of(e) << "\n";
    return 1;
  }
  return 0;
}
