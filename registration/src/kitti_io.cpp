#include "carat/registration/kitti_io.hpp"

#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "carat/solver/atomic_file.hpp"
#include "carat/solver/error.hpp"

namespace carat {

PointCloud read_kitti_bin(const std::filesystem::path& path, KittiFormat format,
                          const ReadOptions& options) {
  const std::string name = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw Error(name + ": no such file");
  const auto bytes = std::filesystem::file_size(path, ec);
  if (ec) throw Error(name + ": cannot read the file size");
  const std::size_t record = format == KittiFormat::kXyzi ? 16 : 12;
  if (bytes == 0) throw Error(name + ": empty file");
  if (bytes % record != 0) {
    throw Error(name + ": " + std::to_string(bytes) + " bytes is not a whole number of " +
                std::to_string(record) + "-byte records (truncated, or not " +
                (format == KittiFormat::kXyzi ? "x y z intensity" : "x y z") + " float32 data)");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(name + ": cannot open for reading");
  std::vector<char> buffer(bytes);
  if (!in.read(buffer.data(), static_cast<std::streamsize>(bytes)))
    throw Error(name + ": read error");
  const std::size_t n = bytes / record;
  PointCloud cloud;
  cloud.points.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    float xyz[3];
    std::memcpy(xyz, buffer.data() + i * record, sizeof(xyz));
    if (!std::isfinite(xyz[0]) || !std::isfinite(xyz[1]) || !std::isfinite(xyz[2])) {
      if (options.drop_non_finite) continue;
      throw Error(name + ": point " + std::to_string(i) + " is not finite");
    }
    cloud.points.emplace_back(xyz[0], xyz[1], xyz[2]);
  }
  return cloud;
}

void write_kitti_bin(const std::filesystem::path& path, const PointCloud& cloud,
                     KittiFormat format) {
  static_assert(std::endian::native == std::endian::little, "KITTI files are little-endian");
  const std::size_t floats = format == KittiFormat::kXyzi ? 4 : 3;
  std::vector<float> buffer(cloud.size() * floats, 0.0f);
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3f& p = cloud.points[i];
    if (!p.allFinite()) {
      throw Error(path.string() + ": point " + std::to_string(i) + " is not finite");
    }
    for (int c = 0; c < 3; ++c) buffer[i * floats + c] = p[c];
  }
  write_file_atomically(path, [&](std::ostream& out) {
    out.write(reinterpret_cast<const char*>(buffer.data()),
              static_cast<std::streamsize>(buffer.size() * sizeof(float)));
  });
}

}  // namespace carat
