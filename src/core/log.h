// Logging to stderr and a terminal progress bar for long work.
#pragma once
#include <chrono>
#include <cstdint>
#include <string>
#include <vector>

namespace ddhgs::core {

enum class LogLevel { Quiet = 0, Normal = 1, Verbose = 2 };
void set_log_level(LogLevel level);
LogLevel log_level();

void log_info(const std::string& message);
void log_warn(const std::string& message);
void log_debug(const std::string& message);

// Redraws one stderr line at most ~10 times per second. On a non-terminal
// (CI logs) it prints a plain line every 10 % instead of carriage returns.
class ProgressBar {
 public:
  ProgressBar(std::string label, int64_t total);
  ~ProgressBar();
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;

  // Sets the absolute position and an optional status text (e.g. "loss 0.031").
  void update(int64_t done, const std::string& status = "");
  void finish(const std::string& status = "");

 private:
  void draw(bool final_line);

  std::string label_;
  int64_t total_;
  int64_t done_ = 0;
  int64_t first_ = -1;  // position at the first update (a resumed job starts there)
  std::string status_;
  bool tty_;
  bool finished_ = false;
  int last_decile_ = -1;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_;
};

// A number as printf's %g writes it: "0.1", "1082.5", "1e+06".
std::string format_g(double value);

// "1h02m", "3m05s", "12.3s".
std::string format_duration(double seconds);

// Names for a one-line message: "a, b, c", the first `most` of them and
// " and N more" after.
std::string format_names(const std::vector<std::string>& names, size_t most = 5);

}  // namespace ddhgs::core
