// Fuzzes the PCD reader in memory: any input must read or throw carat::Error, never crash, hang
// or leak; a cloud that reads has only finite points and no more than the announced limit.
// Mutations are header-aware (header_mutator.hpp) and use fuzz/pcd.dict (header keywords and
// boundary numbers such as 2^32, 2^62, 2^64 - 1).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "carat/base/error.hpp"
#include "carat/registration/io/point_cloud_io.hpp"
#include "header_mutator.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  carat::ReadOptions options;
  options.drop_non_finite = size % 2 == 0;
  options.max_points = size % 3 == 0 ? 1000 : 100'000'000;
  try {
    const carat::PointCloud cloud = carat::parse_pcd(bytes, "fuzz.pcd", options);
    if (cloud.size() > options.max_points) __builtin_trap();
    for (const auto& p : cloud.points) {
      if (!p.allFinite()) __builtin_trap();
    }
  } catch (const carat::Error&) {
  }
  return 0;
}

extern "C" std::size_t LLVMFuzzerCustomMutator(std::uint8_t* data, std::size_t size,
                                               std::size_t max_size, unsigned seed) {
  return carat::fuzz::mutate_header_number(data, size, max_size, seed, "\nDATA");
}
