#include "carat/registration/io/kitti_io.hpp"

#include <bit>
#include <cmath>
#include <cstring>
#include <new>
#include <string>
#include <vector>

#include "carat/base/atomic_file.hpp"
#include "carat/base/error.hpp"
#include "carat/base/input_file.hpp"

namespace carat {
namespace {

/// Records read at a time.
constexpr std::size_t kChunkRecords = 65536;

PointCloud read_kitti_from(ByteSource& source, KittiFormat format, const ReadOptions& options) {
  static_assert(std::endian::native == std::endian::little, "KITTI files are little-endian");
  const std::string& name = source.name();
  const std::size_t record = format == KittiFormat::kXyzi ? 16 : 12;
  const std::uint64_t bytes = source.remaining().value_or(0);
  if (bytes == 0) throw Error(name + ": empty file");
  if (bytes % record != 0) {
    throw Error(name + ": " + std::to_string(bytes) + " bytes is not a whole number of " +
                std::to_string(record) + "-byte records (truncated, or not " +
                (format == KittiFormat::kXyzi ? "x y z intensity" : "x y z") + " float32 data)");
  }
  const std::uint64_t n = bytes / record;
  if (n > options.max_points) {
    throw Error(name + ": holds " + std::to_string(n) + " points, more than the " +
                std::to_string(options.max_points) + " carat reads from one file");
  }
  PointCloud cloud;
  try {
    cloud.points.reserve(static_cast<std::size_t>(n));
  } catch (const std::bad_alloc&) {
    throw Error(name + ": not enough memory for " + std::to_string(n) + " points");
  }
  std::vector<char> chunk(kChunkRecords * record);
  std::uint64_t index = 0;
  while (index < n) {
    const std::size_t count =
        static_cast<std::size_t>(std::min<std::uint64_t>(kChunkRecords, n - index));
    std::size_t got = 0;
    while (got < count * record) {
      const std::size_t part = source.read(chunk.data() + got, count * record - got);
      if (part == 0) throw Error(name + ": the file became shorter while it was read");
      got += part;
    }
    for (std::size_t k = 0; k < count; ++k, ++index) {
      float xyz[3];
      std::memcpy(xyz, chunk.data() + k * record, sizeof(xyz));
      if (!std::isfinite(xyz[0]) || !std::isfinite(xyz[1]) || !std::isfinite(xyz[2])) {
        if (options.drop_non_finite) continue;
        throw Error(name + ": point " + std::to_string(index) + " is not finite");
      }
      cloud.points.emplace_back(xyz[0], xyz[1], xyz[2]);
    }
  }
  return cloud;
}

}  // namespace

PointCloud read_kitti_bin(const std::filesystem::path& path, KittiFormat format,
                          const ReadOptions& options) {
  InputFile file(path, InputKind::kRegular);
  return read_kitti_from(file, format, options);
}

PointCloud parse_kitti_bin(std::string_view bytes, KittiFormat format, const std::string& name,
                           const ReadOptions& options) {
  MemorySource source(bytes, name);
  return read_kitti_from(source, format, options);
}

void write_kitti_bin(const std::filesystem::path& path, const PointCloud& cloud,
                     KittiFormat format) {
  const std::size_t floats = format == KittiFormat::kXyzi ? 4 : 3;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (!cloud.points[i].allFinite()) {
      throw Error(path.string() + ": point " + std::to_string(i) + " is not finite");
    }
  }
  write_file_atomically(path, [&](std::ostream& out) {
    std::vector<float> buffer;
    buffer.reserve(kChunkRecords * floats);
    for (std::size_t first = 0; first < cloud.size(); first += kChunkRecords) {
      const std::size_t last = std::min(cloud.size(), first + kChunkRecords);
      buffer.assign((last - first) * floats, 0.0f);
      for (std::size_t i = first; i < last; ++i) {
        for (std::size_t c = 0; c < 3; ++c) buffer[(i - first) * floats + c] = cloud.points[i][c];
      }
      out.write(reinterpret_cast<const char*>(buffer.data()),
                static_cast<std::streamsize>(buffer.size() * sizeof(float)));
    }
  });
}

const char* to_string(KittiFormat format) {
  switch (format) {
    case KittiFormat::kXyzi:
      return "xyzi";
    case KittiFormat::kXyz:
      return "xyz";
  }
  return "unknown";
}

KittiFormat parse_kitti_format(std::string_view name) {
  if (name == "xyzi") return KittiFormat::kXyzi;
  if (name == "xyz") return KittiFormat::kXyz;
  throw Error("unknown KITTI .bin format " + quote_bytes(name) + " (valid: xyzi, xyz)");
}

}  // namespace carat
