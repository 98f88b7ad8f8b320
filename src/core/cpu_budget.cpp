#include "core/cpu_budget.h"

#include <sched.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <sstream>
#include <vector>

namespace ddhgs::core {
namespace {

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  if (!in) return "";
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

std::optional<double> positive_number(const std::string& text) {
  try {
    const double v = std::stod(text);
    if (std::isfinite(v) && v > 0) return v;
  } catch (const std::exception&) {
  }
  return std::nullopt;
}

std::optional<double> ratio(const std::string& quota, const std::string& period) {
  const auto q = positive_number(quota), p = positive_number(period);
  if (!q || !p) return std::nullopt;
  return *q / *p;
}

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> parts;
  std::string part;
  std::istringstream in(s);
  while (std::getline(in, part, sep)) parts.push_back(part);
  return parts;
}

// mountinfo writes a space in a path as \040 (octal escapes).
std::string unescape(const std::string& s) {
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '\\' && i + 3 < s.size() && std::isdigit(static_cast<unsigned char>(s[i + 1]))) {
      out += char(std::stoi(s.substr(i + 1, 3), nullptr, 8));
      i += 3;
    } else {
      out += s[i];
    }
  }
  return out;
}

struct CgroupMount {
  std::string root;   // the part of the hierarchy mounted (a container's own cgroup)
  std::string point;  // where it is mounted
};

// The mount of cgroup v2 (v1 == false) or of the v1 hierarchy holding the
// cpu controller.
std::optional<CgroupMount> find_mount(const std::string& mountinfo, bool v1) {
  std::istringstream in(mountinfo);
  std::string line;
  while (std::getline(in, line)) {
    const size_t dash = line.find(" - ");
    if (dash == std::string::npos) continue;
    const auto head = split(line.substr(0, dash), ' ');
    const auto tail = split(line.substr(dash + 3), ' ');
    if (head.size() < 5 || tail.size() < 3) continue;
    if (!v1 && tail[0] == "cgroup2") return CgroupMount{unescape(head[3]), unescape(head[4])};
    if (v1 && tail[0] == "cgroup") {
      const auto options = split(tail[2], ',');
      if (std::find(options.begin(), options.end(), "cpu") != options.end())
        return CgroupMount{unescape(head[3]), unescape(head[4])};
    }
  }
  return std::nullopt;
}

// This process's cgroup path in the v2 hierarchy ("0::/path") or in the v1
// hierarchy holding the cpu controller ("4:cpu,cpuacct:/path").
std::optional<std::string> own_cgroup(const std::string& proc_cgroup, bool v1) {
  std::istringstream in(proc_cgroup);
  std::string line;
  while (std::getline(in, line)) {
    const size_t a = line.find(':'), b = a == std::string::npos ? a : line.find(':', a + 1);
    if (b == std::string::npos) continue;
    const std::string controllers = line.substr(a + 1, b - a - 1), path = line.substr(b + 1);
    if (!v1 && line.substr(0, a) == "0" && controllers.empty()) return path;
    const auto names = split(controllers, ',');
    if (v1 && std::find(names.begin(), names.end(), "cpu") != names.end()) return path;
  }
  return std::nullopt;
}

// The folders from the process's own cgroup up to the mount point.
std::vector<std::string> cgroup_folders(const std::string& root, const CgroupMount& mount,
                                        const std::string& path) {
  std::string relative = path;
  // A container sees its own cgroup as the mount's root: strip that prefix.
  if (mount.root != "/" && relative.rfind(mount.root, 0) == 0)
    relative = relative.substr(mount.root.size());
  std::vector<std::string> folders;
  while (true) {
    while (relative.size() > 1 && relative.back() == '/') relative.pop_back();
    folders.push_back(root + mount.point + (relative == "/" ? "" : relative));
    const size_t slash = relative.rfind('/');
    if (relative.empty() || relative == "/" || slash == std::string::npos) break;
    relative = slash == 0 ? "/" : relative.substr(0, slash);
  }
  return folders;
}

void take_min(std::optional<double>& best, std::optional<double> v) {
  if (v && (!best || *v < *best)) best = v;
}

}  // namespace

std::optional<double> parse_cpu_max(const std::string& text) {
  std::istringstream in(text);
  std::string quota, period;
  if (!(in >> quota >> period) || quota == "max") return std::nullopt;
  return ratio(quota, period);
}

std::optional<double> parse_cfs_quota(const std::string& quota, const std::string& period) {
  return ratio(quota, period);
}

std::optional<double> cgroup_cpu_quota(const std::string& root) {
  const std::string proc_cgroup = read_text(root + "/proc/self/cgroup");
  const std::string mountinfo = read_text(root + "/proc/self/mountinfo");
  std::optional<double> best;
  for (bool v1 : {false, true}) {
    const auto mount = find_mount(mountinfo, v1);
    const auto path = own_cgroup(proc_cgroup, v1);
    if (!mount || !path) continue;
    for (const std::string& folder : cgroup_folders(root, *mount, *path)) {
      if (v1)
        take_min(best, parse_cfs_quota(read_text(folder + "/cpu.cfs_quota_us"),
                                       read_text(folder + "/cpu.cfs_period_us")));
      else
        take_min(best, parse_cpu_max(read_text(folder + "/cpu.max")));
    }
  }
  return best;
}

int affinity_cpus() {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof(set), &set) != 0)
    return std::max(1L, sysconf(_SC_NPROCESSORS_ONLN));
  return std::max(1, CPU_COUNT(&set));
}

CpuBudget cpu_budget() {
  CpuBudget b;
  b.machine = int(std::max(1L, sysconf(_SC_NPROCESSORS_ONLN)));
  b.affinity = affinity_cpus();
  b.quota = cgroup_cpu_quota();
  b.cpus = b.affinity;
  b.source = b.affinity < b.machine ? "affinity mask" : "all cores";
  if (b.quota && std::ceil(*b.quota) < b.cpus) {
    b.cpus = std::max(1, int(std::ceil(*b.quota)));
    b.source = "cgroup quota";
  }
  return b;
}

}  // namespace ddhgs::core
