// Maps a folder of LiDAR scans with the library, loops included: map_folder() below is all the
// user code (open the scans, close loops, build the dense graph, minimize the registration
// errors). With a folder and a guess file as arguments it maps them and prints the poses; with
// none it maps the real KITTI 07 frames (CARAT_DATA_DIR/kitti07_seq5) from their reference
// perturbed by 0.3 m / 3 deg, else a simulated two-lap drive from a heading-drifting odometry
// guess. Prints the ATE before and after (one JSON object with --json) and exits 1 unless the
// map ends closer to the reference than it started.
#include <unistd.h>

#include <Eigen/Geometry>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/registration/io/scan_folder.hpp"
#include "carat/registration/io/trajectory_io.hpp"
#include "carat/registration/mapping.hpp"
#include "carat/registration/pose_perturbation.hpp"
#include "carat/registration/scan_opening.hpp"
#include "carat/registration/trajectory_error.hpp"
#include "carat/sim/drift.hpp"
#include "carat/sim/kitti_writer.hpp"
#include "carat/sim/world.hpp"

namespace fs = std::filesystem;

/// The user code: the scans of `folder` mapped from the guess in `guess_file` (KITTI poses, one
/// per scan in name order), loops closed first. Returns T_world_frame per scan.
std::vector<Eigen::Isometry3d> map_folder(const fs::path& folder, const fs::path& guess_file) {
  const std::vector<carat::ScanFile> scans = carat::list_scan_folder(folder);
  const carat::Trajectory guess = carat::poses_in_scan_order(
      carat::read_trajectory(guess_file, carat::TrajectoryFormat::kKitti),
      carat::TrajectoryFormat::kKitti, scans, guess_file.string());
  carat::OpenScansOptions open;  // 0.5 m voxels, every scan read now
  open.num_threads = 2;
  const auto frames = carat::open_scans(scans, open);
  carat::MappingOptions options;  // GRE with exact 29-row factors over the dense graph
  options.num_threads = 2;
  options.close_loops = true;
  options.registration.rounds = 2;  // correspondences searched again at the first result
  return carat::map_frames(*frames, guess.poses, options).T_world_frame;
}

namespace {

/// A drive to map: its folder, the guess file, and the reference poses (empty: none).
struct Drive {
  fs::path folder, guess;
  std::vector<Eigen::Isometry3d> reference;
  std::string source;
};

/// The real KITTI 07 frames with a perturbed guess, when CARAT_DATA_DIR holds them.
bool kitti07(const fs::path& scratch, Drive* drive) {
  const char* data = std::getenv("CARAT_DATA_DIR");
  const fs::path dir = fs::path(data != nullptr ? data : "../shared/data") / "kitti07_seq5";
  std::error_code ec;
  if (!fs::is_regular_file(dir / "graph.txt", ec)) return false;
  const auto scans = carat::list_scan_folder(dir);
  const carat::TrajectoryFormat graph = carat::TrajectoryFormat::kGraph;
  drive->reference = carat::poses_in_scan_order(carat::read_trajectory(dir / "graph.txt", graph),
                                                graph, scans, (dir / "graph.txt").string())
                         .poses;
  carat::Trajectory guess;
  guess.poses = carat::perturb_poses(drive->reference, 0.3, 3.0, 1);
  for (std::size_t k = 0; k < guess.poses.size(); ++k) guess.stamps.push_back(double(k));
  drive->folder = dir;
  drive->guess = scratch / "guess.txt";
  carat::write_trajectory(drive->guess, guess, carat::TrajectoryFormat::kKitti);
  drive->source = "KITTI 07 (" + dir.string() + ")";
  return true;
}

/// A simulated two-lap drive whose odometry guess drifts by 10 degrees per 100 m.
void simulated(const fs::path& scratch, Drive* drive) {
  const carat::SyntheticWorld world{carat::SyntheticWorldOptions{}};
  carat::SyntheticTrajectoryOptions path;
  path.frames = 40;
  drive->folder = scratch / "scans";
  carat::write_synthetic_drive(drive->folder, world, path);
  drive->reference = world.trajectory(path);
  carat::DriftOptions drift;
  drift.heading_bias_deg = 0.1;
  carat::Trajectory guess;
  guess.poses = carat::apply_drift(drive->reference, drift);
  for (std::size_t k = 0; k < guess.poses.size(); ++k) guess.stamps.push_back(double(k));
  drive->guess = scratch / "guess.txt";
  carat::write_trajectory(drive->guess, guess, carat::TrajectoryFormat::kKitti);
  drive->source = "a simulated drive (40 frames, 2 laps)";
}

}  // namespace

int main(int argc, char** argv) {
  bool json = false;
  std::vector<std::string> paths;
  for (int k = 1; k < argc; ++k) {
    if (std::strcmp(argv[k], "--json") == 0) {
      json = true;
    } else {
      paths.emplace_back(argv[k]);
    }
  }
  const fs::path scratch =
      fs::temp_directory_path() / ("carat-map-scans-" + std::to_string(::getpid()));
  try {
    Drive drive;
    if (paths.size() == 2) {
      drive.folder = paths[0];
      drive.guess = paths[1];
      drive.source = paths[0];
    } else if (!paths.empty()) {
      std::fprintf(stderr, "usage: map_scans [--json] [FOLDER GUESS_POSES.txt]\n");
      return 2;
    } else {
      fs::create_directories(scratch);
      if (!kitti07(scratch, &drive)) simulated(scratch, &drive);
    }
    const std::vector<Eigen::Isometry3d> guess =
        carat::read_trajectory(drive.guess, carat::TrajectoryFormat::kKitti).poses;
    const std::vector<Eigen::Isometry3d> mapped = map_folder(drive.folder, drive.guess);
    fs::remove_all(scratch);
    if (drive.reference.empty()) {
      for (const Eigen::Isometry3d& T : mapped) {
        const Eigen::Matrix<double, 3, 4> m = T.matrix().topRows<3>();
        for (int k = 0; k < 12; ++k) std::printf(k < 11 ? "%.9g " : "%.9g\n", m(k / 4, k % 4));
      }
      return 0;
    }
    const double before = carat::compute_ate(guess, drive.reference).rmse;
    const double after = carat::compute_ate(mapped, drive.reference).rmse;
    const bool ok = after < before && after < 0.05;
    if (json) {
      std::printf(
          "{\n  \"source\": \"%s\",\n  \"frames\": %zu,\n  \"ate_rmse_before\": %.6g,\n"
          "  \"ate_rmse_after\": %.6g,\n  \"ok\": %s\n}\n",
          drive.source.c_str(), mapped.size(), before, after, ok ? "true" : "false");
    } else {
      std::printf("%s: %zu frames, ATE RMSE %.4f m from the guess, %.4f m mapped: %s\n",
                  drive.source.c_str(), mapped.size(), before, after, ok ? "ok" : "FAILED");
    }
    return ok ? 0 : 1;
  } catch (const carat::Error& e) {
    std::error_code ec;
    fs::remove_all(scratch, ec);
    std::fprintf(stderr, "map_scans: %s\n", e.what());
    return 1;
  }
}
