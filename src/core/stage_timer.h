// Time spent per named stage of a training step (render forward, SSIM, Adam,
// ...), for the benchmark that splits an iteration by stage.
//
// Stages nest: a stage's figures exclude the stages opened inside it, so the
// figures of all stages add up to the time spent inside any of them. Scopes
// belong on the thread that drives the step (the autograd backward of CPU
// graphs runs there too), outside parallel regions. Off by default; a scope
// then costs one atomic load.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace ddhgs::core {

void enable_stage_timing(bool on);
bool stage_timing_enabled();

struct StageTotals {
  std::string name;
  int64_t calls = 0;
  double wall_s = 0;
  double user_s = 0;    // CPU time of all threads, user mode
  double system_s = 0;  // CPU time of all threads, kernel mode (page faults, mmap)
  int64_t minor_faults = 0;
};

// Exclusive totals since the last reset, in order of first use.
std::vector<StageTotals> stage_totals();
void reset_stage_totals();

class StageScope {
 public:
  explicit StageScope(const char* name);  // name: a string literal
  ~StageScope();
  StageScope(const StageScope&) = delete;
  StageScope& operator=(const StageScope&) = delete;

 private:
  bool active_;
};

}  // namespace ddhgs::core
