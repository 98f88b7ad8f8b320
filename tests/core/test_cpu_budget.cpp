// core::cpu_budget: the cgroup quota parsers on sample cpu.max and
// cpu.cfs_quota_us / cpu.cfs_period_us files, the search through a fake
// /proc and /sys tree (v2, v1, a container's own cgroup as the mount's root,
// nested limits), and the live affinity mask.
#include <gtest/gtest.h>
#include <sched.h>

#include <fstream>

#include "core/cpu_budget.h"
#include "core/threads.h"
#include "support/test_support.h"

using namespace ddhgs;
namespace fs = std::filesystem;

namespace {

void write(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream(path) << text;
}

// A fake /proc/self: the process's cgroup lines and the mount table.
void fake_proc(const fs::path& root, const std::string& cgroup, const std::string& mountinfo) {
  write(root / "proc/self/cgroup", cgroup);
  write(root / "proc/self/mountinfo", mountinfo);
}

// A cgroup v1 folder's quota and period (microseconds).
void write_cfs(const fs::path& folder, const std::string& quota) {
  write(folder / "cpu.cfs_quota_us", quota + "\n");
  write(folder / "cpu.cfs_period_us", "100000\n");
}

TEST(CpuBudget, ParsesCgroupV2CpuMax) {
  EXPECT_FALSE(core::parse_cpu_max("max 100000\n"));
  EXPECT_DOUBLE_EQ(*core::parse_cpu_max("150000 100000\n"), 1.5);
  EXPECT_DOUBLE_EQ(*core::parse_cpu_max("400000 100000"), 4.0);
  EXPECT_DOUBLE_EQ(*core::parse_cpu_max("50000 200000\n"), 0.25);
  EXPECT_FALSE(core::parse_cpu_max(""));
  EXPECT_FALSE(core::parse_cpu_max("150000"));
  EXPECT_FALSE(core::parse_cpu_max("0 100000"));
  EXPECT_FALSE(core::parse_cpu_max("abc 100000"));
  EXPECT_FALSE(core::parse_cpu_max("150000 0"));
}

TEST(CpuBudget, ParsesCgroupV1CfsQuota) {
  EXPECT_FALSE(core::parse_cfs_quota("-1\n", "100000\n"));
  EXPECT_DOUBLE_EQ(*core::parse_cfs_quota("250000\n", "100000\n"), 2.5);
  EXPECT_DOUBLE_EQ(*core::parse_cfs_quota("100000", "100000"), 1.0);
  EXPECT_FALSE(core::parse_cfs_quota("", "100000"));
  EXPECT_FALSE(core::parse_cfs_quota("100000", ""));
}

// A cgroup v2 machine: the tightest limit on the path from the process's
// cgroup up to the mount wins; one outside that path does not count.
TEST(CpuBudget, FindsTheTightestV2QuotaOnTheProcessPath) {
  const fs::path root = test::temp_dir("cpu_budget_v2");
  fake_proc(root, "0::/user.slice/job42/step0\n",
            "22 1 0:21 / /proc rw - proc proc rw\n"
            "30 22 0:26 / /sys/fs/cgroup rw,nosuid shared:4 - cgroup2 cgroup2 rw,nsdelegate\n");
  const fs::path cg = root / "sys/fs/cgroup";
  write(cg / "cpu.max", "max 100000\n");
  write(cg / "user.slice/cpu.max", "800000 100000\n");
  write(cg / "user.slice/job42/cpu.max", "300000 100000\n");
  write(cg / "user.slice/job42/step0/cpu.max", "max 100000\n");
  write(cg / "other/cpu.max", "10000 100000\n");
  const auto quota = core::cgroup_cpu_quota(root.string());
  ASSERT_TRUE(quota);
  EXPECT_DOUBLE_EQ(*quota, 3.0);
  write(cg / "user.slice/job42/step0/cpu.max", "120000 100000\n");
  EXPECT_DOUBLE_EQ(*core::cgroup_cpu_quota(root.string()), 1.2);
}

// Inside a container the mount's root is the container's own cgroup, which
// /proc/self/cgroup names in full.
TEST(CpuBudget, ReadsAContainersOwnCgroupAtTheMountPoint) {
  const fs::path root = test::temp_dir("cpu_budget_container");
  fake_proc(root, "0::/docker/abc123\n",
            "700 650 0:30 /docker/abc123 /sys/fs/cgroup ro,nosuid - cgroup2 cgroup rw\n");
  write(root / "sys/fs/cgroup/cpu.max", "200000 100000\n");
  EXPECT_DOUBLE_EQ(*core::cgroup_cpu_quota(root.string()), 2.0);
}

// cgroup v1: the hierarchy holding the cpu controller (joined with cpuacct
// here), a mount point with an escaped space.
TEST(CpuBudget, FindsTheV1CpuHierarchy) {
  const fs::path root = test::temp_dir("cpu_budget_v1");
  fake_proc(root,
            "4:memory:/slurm/uid_1/job_7\n3:cpu,cpuacct:/slurm/uid_1/job_7\n1:name=systemd:/\n",
            "31 23 0:28 / /sys/fs/cgroup rw - tmpfs tmpfs rw,mode=755\n"
            "32 31 0:29 / /sys/fs/cgroup/cpu\\040acct rw,relatime - cgroup cgroup rw,cpu,cpuacct\n"
            "35 31 0:32 / /sys/fs/cgroup/memory rw,relatime - cgroup cgroup rw,memory\n");
  const fs::path cg = root / "sys/fs/cgroup/cpu acct";
  write_cfs(cg, "-1");
  write_cfs(cg / "slurm/uid_1/job_7", "400000");
  // A quota on the memory hierarchy's folder is not the cpu controller's.
  write_cfs(root / "sys/fs/cgroup/memory/slurm/uid_1/job_7", "10000");
  EXPECT_DOUBLE_EQ(*core::cgroup_cpu_quota(root.string()), 4.0);
}

TEST(CpuBudget, NoQuotaWhenNothingLimits) {
  const fs::path root = test::temp_dir("cpu_budget_none");
  EXPECT_FALSE(core::cgroup_cpu_quota(root.string()));  // no /proc at all
  fake_proc(root, "0::/\n", "30 22 0:26 / /sys/fs/cgroup rw - cgroup2 cgroup2 rw\n");
  write(root / "sys/fs/cgroup/cpu.max", "max 100000\n");
  EXPECT_FALSE(core::cgroup_cpu_quota(root.string()));
}

// The live mask: narrowed to one CPU, the budget follows it.
TEST(CpuBudget, FollowsTheAffinityMask) {
  cpu_set_t saved;
  ASSERT_EQ(sched_getaffinity(0, sizeof saved, &saved), 0);
  const int before = core::affinity_cpus();
  EXPECT_EQ(before, CPU_COUNT(&saved));
  int first = 0;
  while (!CPU_ISSET(first, &saved)) ++first;
  cpu_set_t one;
  CPU_ZERO(&one);
  CPU_SET(first, &one);
  ASSERT_EQ(sched_setaffinity(0, sizeof one, &one), 0);
  const core::CpuBudget budget = core::cpu_budget();
  ASSERT_EQ(sched_setaffinity(0, sizeof saved, &saved), 0);
  EXPECT_EQ(budget.affinity, 1);
  EXPECT_EQ(budget.cpus, 1);
  if (budget.machine > 1) {
    EXPECT_EQ(budget.source, "affinity mask");
  }
  EXPECT_EQ(core::affinity_cpus(), before);
}

}  // namespace
