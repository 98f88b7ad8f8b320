#include "core/log.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <iostream>

namespace ddhgs::core {
namespace {
LogLevel g_level = LogLevel::Normal;
}

void set_log_level(LogLevel level) {
  g_level = level;
}
LogLevel log_level() {
  return g_level;
}

void log_info(const std::string& message) {
  if (g_level >= LogLevel::Normal) std::cerr << message << "\n";
}
void log_warn(const std::string& message) {
  std::cerr << "warning: " << message << "\n";
}
void log_debug(const std::string& message) {
  if (g_level >= LogLevel::Verbose) std::cerr << message << "\n";
}

std::string format_g(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", value);
  return text;
}

std::string format_duration(double seconds) {
  char buf[32];
  if (seconds < 60) {
    std::snprintf(buf, sizeof buf, "%.1fs", seconds);
  } else if (seconds < 3600) {
    std::snprintf(buf, sizeof buf, "%dm%02ds", int(seconds) / 60, int(seconds) % 60);
  } else {
    std::snprintf(buf, sizeof buf, "%dh%02dm", int(seconds) / 3600, (int(seconds) / 60) % 60);
  }
  return buf;
}

std::string format_names(const std::vector<std::string>& names, size_t most) {
  std::string text;
  for (size_t i = 0; i < names.size() && i < most; ++i) text += (i ? ", " : "") + names[i];
  if (names.size() > most) text += " and " + std::to_string(names.size() - most) + " more";
  return text;
}

ProgressBar::ProgressBar(std::string label, int64_t total)
    : label_(std::move(label)),
      total_(std::max<int64_t>(total, 1)),
      tty_(isatty(STDERR_FILENO) != 0),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_) {}

ProgressBar::~ProgressBar() {
  if (!finished_ && tty_ && g_level >= LogLevel::Normal) std::cerr << "\n";
}

void ProgressBar::update(int64_t done, const std::string& status) {
  done_ = std::min(done, total_);
  if (first_ < 0) first_ = done_;
  status_ = status;
  auto now = std::chrono::steady_clock::now();
  if (tty_) {
    if (now - last_draw_ < std::chrono::milliseconds(100)) return;
    last_draw_ = now;
    draw(false);
  } else {
    int decile = int(10 * done_ / total_);
    if (decile == last_decile_) return;
    last_decile_ = decile;
    draw(false);
  }
}

void ProgressBar::finish(const std::string& status) {
  if (finished_) return;
  done_ = total_;
  if (!status.empty()) status_ = status;
  draw(true);
  finished_ = true;
}

void ProgressBar::draw(bool final_line) {
  if (g_level < LogLevel::Normal) return;
  double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  double frac = double(done_) / double(total_);
  // Items per second since the first update, so a resumed job's rate does
  // not count the work done before it.
  const int64_t since = done_ - std::max<int64_t>(first_, 0);
  double rate = elapsed > 0 ? since / elapsed : 0.0;
  std::string eta = (rate > 0 && !final_line) ? format_duration((total_ - done_) / rate) : "";
  const int width = 24;
  int filled = int(frac * width);
  std::string bar = std::string(filled, '#') + std::string(width - filled, '.');
  char head[160];
  std::snprintf(head, sizeof head, "%s [%s] %lld/%lld %5.1f%% %.2f/s %s%s", label_.c_str(),
                bar.c_str(), (long long)done_, (long long)total_, 100.0 * frac, rate,
                final_line ? "in " : "eta ",
                final_line ? format_duration(elapsed).c_str() : eta.c_str());
  std::string line = std::string(head) + (status_.empty() ? "" : "  " + status_);
  if (tty_) {
    std::cerr << "\r\033[K" << line << (final_line ? "\n" : "") << std::flush;
  } else {
    std::cerr << line << "\n";
  }
}

}  // namespace ddhgs::core
