#include "carat/sim/kitti_writer.hpp"

#include <tbb/parallel_for.h>

#include <atomic>
#include <cstdio>
#include <span>
#include <string>
#include <system_error>

#include "carat/base/atomic_file.hpp"
#include "carat/base/error.hpp"
#include "carat/registration/io/kitti_io.hpp"

namespace carat {
namespace {

void write_kitti_poses(const std::filesystem::path& path,
                       std::span<const Eigen::Isometry3d> T_world_frame) {
  std::string text;
  for (const Eigen::Isometry3d& T : T_world_frame) {
    const Eigen::Matrix4d M = T.matrix();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) {
        char number[40];
        std::snprintf(number, sizeof(number), "%.9g", M(r, c));
        if (r + c > 0) text += ' ';
        text += number;
      }
    }
    text += '\n';
  }
  write_file_atomically(path, [&](std::ostream& out) { out << text; });
}

std::filesystem::path frame_file(const std::filesystem::path& dir, std::size_t k) {
  char name[32];
  std::snprintf(name, sizeof(name), "%06zu.bin", k);
  return dir / name;
}

void create_folder(const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw Error(dir.string() + ": cannot create the directory (" + ec.message() + ")");
}

}  // namespace

void write_synthetic_sequence(const std::filesystem::path& dir, const SyntheticSequence& sequence) {
  if (sequence.scans.size() != sequence.T_world_frame.size()) {
    throw Error("write_synthetic_sequence: " + std::to_string(sequence.scans.size()) +
                " scans but " + std::to_string(sequence.T_world_frame.size()) + " poses");
  }
  create_folder(dir);
  for (std::size_t k = 0; k < sequence.scans.size(); ++k) {
    write_kitti_bin(frame_file(dir, k), sequence.scans[k], KittiFormat::kXyzi);
  }
  write_kitti_poses(dir / "poses.txt", sequence.T_world_frame);
}

std::size_t write_synthetic_drive(const std::filesystem::path& dir, const SyntheticWorld& world,
                                  const SyntheticTrajectoryOptions& options,
                                  const std::function<void(std::size_t, std::size_t)>& progress) {
  const std::vector<Eigen::Isometry3d> poses = world.trajectory(options);
  create_folder(dir);
  std::atomic<std::size_t> points{0}, done{0};
  tbb::parallel_for(std::size_t{0}, poses.size(), [&](std::size_t k) {
    const PointCloud scan =
        world.scan(poses[k], synthetic_frame_noise_seed(world.options().seed, k));
    write_kitti_bin(frame_file(dir, k), scan, KittiFormat::kXyzi);
    points += scan.size();
    if (progress) progress(done.fetch_add(1) + 1, poses.size());
  });
  write_kitti_poses(dir / "poses.txt", poses);
  return points.load();
}

}  // namespace carat
