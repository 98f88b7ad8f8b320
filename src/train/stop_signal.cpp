#include "train/stop_signal.h"

#include <atomic>
#include <csignal>

namespace ddhgs::train {

namespace {

std::atomic<bool> g_stop{false};
std::atomic<int> g_stop_signal{0};

extern "C" void on_stop_signal(int signal) {
  g_stop_signal = signal;
  g_stop = true;
}

}  // namespace

void request_stop() {
  g_stop = true;
}

bool stop_requested() {
  return g_stop;
}

int stop_signal() {
  return g_stop_signal;
}

int interrupted_exit_code() {
  const int signal = stop_signal();
  return 128 + (signal > 0 ? signal : SIGINT);
}

StopSignalGuard::StopSignalGuard() {
  previous_int_ = std::signal(SIGINT, on_stop_signal);
  previous_term_ = std::signal(SIGTERM, on_stop_signal);
  g_stop = false;
  g_stop_signal = 0;
}

StopSignalGuard::~StopSignalGuard() {
  std::signal(SIGINT, previous_int_);
  std::signal(SIGTERM, previous_term_);
}

}  // namespace ddhgs::train
