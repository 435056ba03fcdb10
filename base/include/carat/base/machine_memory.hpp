#pragma once

/// What memory this process may still take, for the checks that refuse work before it starts
/// (options whose cost grows with their value, the linear solver's choice, the coreset's scratch).

#include <cstdint>
#include <string>

namespace carat {

/// Bytes of memory this process may still use: the kernel's MemAvailable, lowered to what is left
/// under the cgroup's limit (memory.max) and under this process's address-space and data limits
/// (RLIMIT_AS, RLIMIT_DATA, as `ulimit -v` sets them) when those are lower.
std::uint64_t available_memory_bytes();

/// Bytes as "12.3 MiB" (binary units: B, KiB, MiB, GiB), for the messages of those checks.
std::string format_bytes(double bytes);

}  // namespace carat
