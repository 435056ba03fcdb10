#include "carat/base/machine_memory.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <fstream>
#include <string>

namespace carat {
namespace {

/// The value (kB) of `key` in a /proc file of "Key: value kB" lines, in bytes; 0 when absent.
std::uint64_t proc_kilobytes(const char* file, const std::string& key) {
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line)) {
    if (line.compare(0, key.size(), key) != 0) continue;
    std::uint64_t kilobytes = 0;
    const char* first = line.data() + key.size();
    const char* last = line.data() + line.size();
    while (first < last && (*first == ' ' || *first == '\t')) ++first;
    std::from_chars(first, last, kilobytes);
    return kilobytes * 1024;
  }
  return 0;
}

/// What is left under a resource limit given the process's current use; none when unlimited.
std::uint64_t left_under(int resource, std::uint64_t used) {
  rlimit limit{};
  if (getrlimit(resource, &limit) != 0 || limit.rlim_cur == RLIM_INFINITY) return UINT64_MAX;
  const auto cap = static_cast<std::uint64_t>(limit.rlim_cur);
  return cap > used ? cap - used : 0;
}

}  // namespace

std::uint64_t available_memory_bytes() {
  std::uint64_t available = proc_kilobytes("/proc/meminfo", "MemAvailable:");
  if (available == 0) {
    const long pages = sysconf(_SC_AVPHYS_PAGES), page = sysconf(_SC_PAGESIZE);
    if (pages > 0 && page > 0) available = static_cast<std::uint64_t>(pages) * page;
  }
  // A cgroup v2 limit, when one is set and lower.
  std::ifstream limit_file("/sys/fs/cgroup/memory.max");
  std::ifstream current_file("/sys/fs/cgroup/memory.current");
  std::uint64_t limit = 0, current = 0;
  if ((limit_file >> limit) && (current_file >> current) && limit > current) {
    available = std::min(available, limit - current);
  }
  // The process's own limits (ulimit -v, ulimit -d), against what it has mapped already.
  available =
      std::min(available, left_under(RLIMIT_AS, proc_kilobytes("/proc/self/status", "VmSize:")));
  available =
      std::min(available, left_under(RLIMIT_DATA, proc_kilobytes("/proc/self/status", "VmData:")));
  return available;
}

std::string format_bytes(double bytes) {
  char text[32];
  if (bytes >= 1024.0 * 1024.0 * 1024.0)
    std::snprintf(text, sizeof(text), "%.2f GiB", bytes / (1024.0 * 1024.0 * 1024.0));
  else if (bytes >= 1024.0 * 1024.0)
    std::snprintf(text, sizeof(text), "%.1f MiB", bytes / (1024.0 * 1024.0));
  else if (bytes >= 1024.0)
    std::snprintf(text, sizeof(text), "%.1f KiB", bytes / 1024.0);
  else
    std::snprintf(text, sizeof(text), "%.0f B", bytes);
  return text;
}

}  // namespace carat
