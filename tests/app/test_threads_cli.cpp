// The thread count a ddhgs process picks, as a user starts it: under
// taskset, inside a cgroup with a CPU quota, and with --threads /
// DDHGS_THREADS overriding both. The -v log names the count and its source.
#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>

#include "support/test_support.h"

namespace ddhgs {
namespace {
namespace fs = std::filesystem;

// ctest sets DDHGS_THREADS for every test; these runs choose for themselves.
// `info` of a missing folder is the cheapest command that sets threads up.
std::string info_command(const std::string& args = "") {
  return "env -u DDHGS_THREADS " + test::ddhgs_binary() + " -v info " +
         (test::temp_dir("threads_cli") / "missing").string() + args;
}

// The -v log's line that names the thread count.
std::string threads_line(const std::string& command) {
  std::string out;
  test::run_command(command, &out);
  const size_t at = out.find(" thread");
  if (at == std::string::npos) return out;
  const size_t begin = out.rfind('\n', at) + 1;
  return out.substr(begin, out.find('\n', at) - begin);
}

long cores() {
  return sysconf(_SC_NPROCESSORS_ONLN);
}

TEST(ThreadsCli, FollowsTheAffinityMask) {
  if (cores() < 2) GTEST_SKIP() << "one core: a mask cannot narrow it";
  const std::string line = threads_line("taskset -c 0 " + info_command());
  EXPECT_NE(line.find("1 thread (affinity mask; 1 of " + std::to_string(cores()) +
                      " cores in the affinity mask"),
            std::string::npos)
      << line;
  const std::string all = threads_line(info_command());
  EXPECT_NE(all.find(std::to_string(cores()) + " threads (all cores"), std::string::npos) << all;
}

TEST(ThreadsCli, FlagAndEnvironmentOverrideTheMask) {
  std::string line = threads_line("taskset -c 0 " + info_command(" --threads 3"));
  EXPECT_NE(line.find("3 threads (--threads;"), std::string::npos) << line;
  std::string out;
  test::run_command("DDHGS_THREADS=2 taskset -c 0 " + test::ddhgs_binary() + " -v info " +
                        (test::temp_dir("threads_cli_env") / "missing").string(),
                    &out);
  EXPECT_NE(out.find("2 threads (DDHGS_THREADS;"), std::string::npos) << out;
}

// A cgroup of our own with a quota of one CPU (cgroup v2 cpu.max or v1
// cpu.cfs_quota_us); needs root and a writable cgroup tree.
struct QuotaCgroup {
  fs::path dir;
  explicit QuotaCgroup(const std::string& name) {
    for (const auto& [base, file, value] :
         {std::tuple<std::string, std::string, std::string>{"/sys/fs/cgroup", "cpu.max",
                                                            "100000 100000"},
          {"/sys/fs/cgroup/cpu", "cpu.cfs_quota_us", "100000"},
          {"/sys/fs/cgroup/cpu,cpuacct", "cpu.cfs_quota_us", "100000"}}) {
      const fs::path d = fs::path(base) / name;
      std::error_code ec;
      if (!fs::create_directory(d, ec)) continue;
      // A real cgroup fills a new folder with its files (on a plain tmpfs
      // under /sys/fs/cgroup it stays empty).
      if (!fs::exists(d / "cgroup.procs")) {
        fs::remove_all(d, ec);
        continue;
      }
      std::ofstream(d / file) << value << "\n";
      std::ifstream check(d / file);
      std::string got;
      std::getline(check, got);
      if (got == value) {
        dir = d;
        return;
      }
      fs::remove(d, ec);
    }
  }
  ~QuotaCgroup() {
    std::error_code ec;
    if (!dir.empty()) fs::remove(dir, ec);  // empty again once the process has ended
  }
};

TEST(ThreadsCli, FollowsACgroupQuota) {
  if (cores() < 2) GTEST_SKIP() << "one core: a one-CPU quota cannot narrow it";
  QuotaCgroup cgroup("ddhgs-test-" + std::to_string(getpid()));
  if (cgroup.dir.empty()) GTEST_SKIP() << "no writable cgroup with a CPU controller (not root?)";
  const std::string line =
      threads_line("sh -c 'echo $$ > " + (cgroup.dir / "cgroup.procs").string() + " && exec " +
                   info_command() + "'");
  EXPECT_NE(line.find("1 thread (cgroup quota;"), std::string::npos) << line;
  EXPECT_NE(line.find("cgroup quota 1 CPUs)"), std::string::npos) << line;
}

}  // namespace
}  // namespace ddhgs
