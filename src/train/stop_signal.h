// How a run is stopped: Ctrl-C, the SIGTERM of batch schedulers and
// `systemctl stop`, or a call from the program itself. The training loop
// checks stop_requested() between steps and saves a checkpoint.
#pragma once

namespace ddhgs::train {

// Asks the running loop to stop at its next step.
void request_stop();
// Whether a stop was asked for since the last StopSignalGuard began.
bool stop_requested();
// The signal that asked (SIGINT, SIGTERM), 0 for request_stop().
int stop_signal();
// The shell's convention for a process stopped by a signal: 128 + signal
// (130 for Ctrl-C, 143 for SIGTERM; 130 for request_stop()).
int interrupted_exit_code();

// While it lives, SIGINT and SIGTERM ask for a stop instead of ending the
// process; it starts with no stop asked for, and the previous handlers come
// back when it ends.
class StopSignalGuard {
 public:
  StopSignalGuard();
  ~StopSignalGuard();
  StopSignalGuard(const StopSignalGuard&) = delete;
  StopSignalGuard& operator=(const StopSignalGuard&) = delete;

 private:
  void (*previous_int_)(int);
  void (*previous_term_)(int);
};

}  // namespace ddhgs::train
