// How many CPUs this process may use: its affinity mask (taskset, Slurm's
// cpusets, docker --cpuset-cpus), further limited by a cgroup CPU quota
// (docker --cpus, Kubernetes limits; cgroup v2 cpu.max or v1
// cpu.cfs_quota_us / cpu.cfs_period_us). The machine's core count alone
// would start 64 threads for a 4-CPU job on a 64-core node.
#pragma once
#include <optional>
#include <string>

namespace ddhgs::core {

// A cgroup v2 cpu.max file ("max 100000" or "150000 100000"): the quota in
// CPUs (1.5), or nothing when unlimited or unreadable.
std::optional<double> parse_cpu_max(const std::string& text);

// A cgroup v1 pair cpu.cfs_quota_us ("-1" or "150000") and
// cpu.cfs_period_us ("100000"): the quota in CPUs, or nothing.
std::optional<double> parse_cfs_quota(const std::string& quota, const std::string& period);

// The tightest CPU quota over this process's cgroup and its ancestors, in
// CPUs, read through /proc/self/cgroup and /proc/self/mountinfo; nothing when
// no quota applies. `root` prefixes every path read (tests point it at a
// fake tree; "" reads the live system).
std::optional<double> cgroup_cpu_quota(const std::string& root = "");

// CPUs in this process's affinity mask (at least 1).
int affinity_cpus();

struct CpuBudget {
  int cpus = 1;                 // what the process may use: min(affinity, ceil(quota))
  int affinity = 1;             // CPUs in the affinity mask
  int machine = 1;              // online cores of the machine
  std::optional<double> quota;  // cgroup quota in CPUs, if any
  std::string source;           // "affinity mask", "cgroup quota" or "all cores"
};

// The live budget of this process.
CpuBudget cpu_budget();

}  // namespace ddhgs::core
