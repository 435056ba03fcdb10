// Fuzzes the KITTI .bin reader (both record layouts) in memory, then a voxel grid on what it
// read: any input must read or throw carat::Error, never crash, hang or leak.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "carat/base/error.hpp"
#include "carat/registration/io/kitti_io.hpp"
#include "carat/registration/voxel_grid.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  for (carat::KittiFormat format : {carat::KittiFormat::kXyz, carat::KittiFormat::kXyzi}) {
    try {
      carat::ReadOptions options;
      options.drop_non_finite = size % 2 == 0;
      options.max_points = size % 3 == 0 ? 100 : 100'000'000;
      const carat::PointCloud cloud = carat::parse_kitti_bin(bytes, format, "fuzz.bin", options);
      if (cloud.size() > options.max_points) __builtin_trap();
      (void)carat::voxel_downsample(cloud, 0.5);
    } catch (const carat::Error&) {
    }
  }
  return 0;
}
