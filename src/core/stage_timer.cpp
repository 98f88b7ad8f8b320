#include "core/stage_timer.h"

#include <sys/resource.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <mutex>

namespace ddhgs::core {
namespace {

std::atomic<bool> g_enabled{false};

struct Sample {
  double wall = 0, user = 0, system = 0;
  int64_t faults = 0;

  static Sample now() {
    Sample s;
    s.wall =
        std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
    rusage u;
    getrusage(RUSAGE_SELF, &u);
    s.user = double(u.ru_utime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec);
    s.system = double(u.ru_stime.tv_sec) + 1e-6 * double(u.ru_stime.tv_usec);
    s.faults = int64_t(u.ru_minflt);
    return s;
  }
  Sample operator-(const Sample& o) const {
    return {wall - o.wall, user - o.user, system - o.system, faults - o.faults};
  }
  Sample& operator+=(const Sample& o) {
    wall += o.wall, user += o.user, system += o.system, faults += o.faults;
    return *this;
  }
};

struct Frame {
  const char* name;
  Sample start;
  Sample children;  // inclusive time of the stages opened inside this one
};

struct Registry {
  std::mutex mutex;
  std::vector<StageTotals> totals;

  void add(const char* name, const Sample& exclusive) {
    std::lock_guard<std::mutex> lock(mutex);
    StageTotals* t = nullptr;
    for (auto& s : totals)
      if (s.name == name) t = &s;
    if (!t) {
      totals.push_back(StageTotals{name});
      t = &totals.back();
    }
    ++t->calls;
    t->wall_s += exclusive.wall;
    t->user_s += exclusive.user;
    t->system_s += exclusive.system;
    t->minor_faults += exclusive.faults;
  }
};

Registry& registry() {
  static Registry r;
  return r;
}

std::vector<Frame>& stack() {
  thread_local std::vector<Frame> frames;
  return frames;
}

}  // namespace

void enable_stage_timing(bool on) {
  g_enabled = on;
}

bool stage_timing_enabled() {
  return g_enabled;
}

std::vector<StageTotals> stage_totals() {
  std::lock_guard<std::mutex> lock(registry().mutex);
  return registry().totals;
}

void reset_stage_totals() {
  std::lock_guard<std::mutex> lock(registry().mutex);
  registry().totals.clear();
}

StageScope::StageScope(const char* name) : active_(g_enabled.load(std::memory_order_relaxed)) {
  if (active_) stack().push_back({name, Sample::now(), {}});
}

StageScope::~StageScope() {
  if (!active_) return;
  std::vector<Frame>& frames = stack();
  const Frame frame = frames.back();
  frames.pop_back();
  const Sample inclusive = Sample::now() - frame.start;
  if (!frames.empty()) frames.back().children += inclusive;
  registry().add(frame.name, inclusive - frame.children);
}

}  // namespace ddhgs::core
