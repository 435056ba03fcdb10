#include "mpi_launch.hpp"

#include <charconv>
#include <cstdlib>
#include <cstring>
#include <initializer_list>

namespace carat::cli {
namespace {

/// The first of `names` set to a decimal number in [0, 2^31), or -1.
int first_number(std::initializer_list<const char*> names) {
  for (const char* name : names) {
    const char* value = std::getenv(name);
    if (value == nullptr) continue;
    int number = -1;
    const char* end = value + std::strlen(value);
    const auto [ptr, ec] = std::from_chars(value, end, number);
    if (ec == std::errc() && ptr == end && ptr != value && number >= 0) return number;
  }
  return -1;
}

}  // namespace

MpiLaunch mpi_launch() {
  MpiLaunch launch;
  const int size = first_number({"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE"});
  const int rank = first_number({"OMPI_COMM_WORLD_RANK", "PMI_RANK", "PMIX_RANK"});
  if (size >= 1 && rank >= 0 && rank < size) {
    launch.size = size;
    launch.rank = rank;
  }
  return launch;
}

}  // namespace carat::cli
