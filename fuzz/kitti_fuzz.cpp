// Fuzzes the KITTI .bin reader (both record layouts) through a scratch file: any input must
// read or throw carat::Error.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "carat/registration/kitti_io.hpp"
#include "carat/registration/voxel_grid.hpp"
#include "carat/solver/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::filesystem::path path =
      std::filesystem::temp_directory_path() /
      ("carat_kitti_fuzz_" + std::to_string(getpid()) + ".bin");
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  for (carat::KittiFormat format : {carat::KittiFormat::kXyz, carat::KittiFormat::kXyzi}) {
    try {
      carat::ReadOptions options;
      options.drop_non_finite = size % 2 == 0;
      const carat::PointCloud cloud = carat::read_kitti_bin(path, format, options);
      (void)carat::voxel_downsample(cloud, 0.5);
    } catch (const carat::Error&) {
    }
  }
  return 0;
}
