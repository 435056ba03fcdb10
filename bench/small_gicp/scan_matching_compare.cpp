// Side-by-side: carat and small_gicp match the same KITTI 00 scan pair in the same run.
// Per scan, each library downsamples the raw source scan (0.25 m voxels), builds its k-d tree,
// estimates k = 10 covariances and aligns the source onto the preprocessed target (GICP, 1 m
// maximum correspondence distance, identity start), with 1 and with 2 threads. Repetitions
// alternate between the two, so both see the same load on a shared machine; the medians, their
// ratio and both results' transforms are printed. Reading the scans is not timed, and the target
// is preprocessed once, before the repetitions.
// small_gicp gets its standard pipeline: preprocess_points() and align() from its
// registration_helper.hpp with its default RegistrationSetting except for the thread count
// (GICP, 0.25 m, 1 m, 20 iterations, its own tolerances). carat runs its defaults
// (AlignSettings), as bench/registration_bench.cpp does.
//
// Usage: scan_matching_compare [--repeat N] [--pause-ms M] [DIR]
//   DIR holds 000000.bin (target) and 000001.bin (source), x y z float32; default
//   ../shared/data/kitti00_pair. Prints "skipped" and exits 0 when the scans are absent.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <small_gicp/ann/kdtree.hpp>
#include <small_gicp/points/point_cloud.hpp>
#include <small_gicp/registration/registration_helper.hpp>
#include <string>
#include <thread>
#include <vector>

#include "carat/base/blas_kernels.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/registration/align.hpp"
#include "carat/registration/covariance.hpp"
#include "carat/registration/io/kitti_io.hpp"
#include "carat/registration/kdtree.hpp"
#include "carat/registration/voxel_grid.hpp"

namespace {

constexpr double kVoxel = 0.25;       // metres
constexpr int kNeighbors = 10;        // covariance neighbours
constexpr double kMaxDistance = 1.0;  // metres

/// carat's preprocessed scan: the downsampled cloud with covariances and its k-d tree.
struct CaratScan {
  std::unique_ptr<carat::PointCloud> cloud;
  std::unique_ptr<carat::KdTree> tree;
};

CaratScan carat_preprocess(const carat::PointCloud& raw, int threads) {
  CaratScan scan{std::make_unique<carat::PointCloud>(carat::voxel_downsample(raw, kVoxel, threads)),
                 nullptr};
  scan.tree = std::make_unique<carat::KdTree>(*scan.cloud);
  carat::CovarianceOptions options;
  options.neighbors = kNeighbors;
  options.num_threads = threads;
  carat::estimate_covariances(*scan.cloud, *scan.tree, options);
  return scan;
}

/// One library's answer for the pair and the time it took.
struct Run {
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();
  int iterations = 0;
  std::size_t source_points = 0;
  double ms = 0.0;
};

Run run_carat(const CaratScan& target, const carat::PointCloud& raw_source, int threads) {
  carat::Stopwatch watch;
  const CaratScan source = carat_preprocess(raw_source, threads);
  carat::AlignSettings settings;
  settings.max_correspondence_distance = kMaxDistance;
  settings.num_threads = threads;
  const carat::AlignResult result = carat::align(*target.cloud, *target.tree, *source.cloud,
                                                 Eigen::Isometry3d::Identity(), settings);
  Run run;
  run.ms = watch.elapsed_ms();
  run.T_target_source = result.T_target_source;
  run.iterations = result.iterations;
  run.source_points = source.cloud->size();
  return run;
}

/// small_gicp's preprocessed scan, as preprocess_points() returns it.
using SmallGicpScan = std::pair<small_gicp::PointCloud::Ptr,
                                std::shared_ptr<small_gicp::KdTree<small_gicp::PointCloud>>>;

Run run_small_gicp(const SmallGicpScan& target, const small_gicp::PointCloud& raw_source,
                   int threads) {
  carat::Stopwatch watch;
  const SmallGicpScan source =
      small_gicp::preprocess_points(raw_source, kVoxel, kNeighbors, threads);
  small_gicp::RegistrationSetting setting;
  setting.type = small_gicp::RegistrationSetting::GICP;
  setting.downsampling_resolution = kVoxel;
  setting.max_correspondence_distance = kMaxDistance;
  setting.num_threads = threads;
  const small_gicp::RegistrationResult result = small_gicp::align(
      *target.first, *source.first, *target.second, Eigen::Isometry3d::Identity(), setting);
  Run run;
  run.ms = watch.elapsed_ms();
  run.T_target_source = result.T_target_source;
  run.iterations = static_cast<int>(result.iterations);
  run.source_points = source.first->size();
  return run;
}

double median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  return n % 2 == 1 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

double rotation_deg(const Eigen::Matrix3d& R) {
  return Eigen::AngleAxisd(R).angle() * 180.0 / M_PI;
}

void print_pose(const char* name, const Run& run) {
  const Eigen::Vector3d t = run.T_target_source.translation();
  std::printf("  %-10s t = (%.4f, %.4f, %.4f) m, %.3f deg, %d iterations, %zu source points\n",
              name, t.x(), t.y(), t.z(), rotation_deg(run.T_target_source.linear()), run.iterations,
              run.source_points);
}

int usage() {
  std::fprintf(stderr, "usage: scan_matching_compare [--repeat N] [--pause-ms M] [DIR]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  carat::use_cpu_blas_kernels(argv);  // OpenBLAS's kernels for this CPU, as `carat` runs them
  int repeat = 15;
  int pause_ms = 20;
  std::filesystem::path dir = std::filesystem::path(CARAT_DATA_DIR) / "kitti00_pair";
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if ((arg == "--repeat" || arg == "--pause-ms") && i + 1 < argc) {
      const int value = std::atoi(argv[++i]);
      if (value < (arg == "--repeat" ? 1 : 0)) return usage();
      (arg == "--repeat" ? repeat : pause_ms) = value;
    } else if (!arg.empty() && arg[0] != '-') {
      dir = arg;
    } else {
      return usage();
    }
  }
  if (!std::filesystem::exists(dir / "000000.bin") ||
      !std::filesystem::exists(dir / "000001.bin")) {
    std::printf("skipped: %s/000000.bin and 000001.bin not found\n", dir.string().c_str());
    return 0;
  }
  const carat::PointCloud carat_target_raw =
      carat::read_kitti_bin(dir / "000000.bin", carat::KittiFormat::kXyz);
  const carat::PointCloud carat_source_raw =
      carat::read_kitti_bin(dir / "000001.bin", carat::KittiFormat::kXyz);
  // small_gicp's own cloud type (homogeneous double points), converted once, untimed.
  const small_gicp::PointCloud small_gicp_target_raw(carat_target_raw.points);
  const small_gicp::PointCloud small_gicp_source_raw(carat_source_raw.points);

  std::printf(
      "KITTI 00 pair %s: %zu target / %zu source points; per scan = preprocess the "
      "source (%.2f m, k = %d) + GICP align (%.1f m); %d alternating repetitions\n",
      dir.string().c_str(), carat_target_raw.size(), carat_source_raw.size(), kVoxel, kNeighbors,
      kMaxDistance, repeat);
  for (const int threads : {1, 2}) {
    const CaratScan carat_target = carat_preprocess(carat_target_raw, threads);
    const SmallGicpScan small_gicp_target =
        small_gicp::preprocess_points(small_gicp_target_raw, kVoxel, kNeighbors, threads);
    // One untimed round each to warm caches, thread pools and the allocator.
    Run carat_run = run_carat(carat_target, carat_source_raw, threads);
    Run small_gicp_run = run_small_gicp(small_gicp_target, small_gicp_source_raw, threads);
    std::vector<double> carat_ms, small_gicp_ms;
    for (int r = 0; r < repeat; ++r) {
      // Alternate which goes first, and let the other's idle workers settle in between.
      for (int turn = 0; turn < 2; ++turn) {
        std::this_thread::sleep_for(std::chrono::milliseconds(pause_ms));
        if ((turn == 0) == (r % 2 == 0)) {
          carat_run = run_carat(carat_target, carat_source_raw, threads);
          carat_ms.push_back(carat_run.ms);
        } else {
          small_gicp_run = run_small_gicp(small_gicp_target, small_gicp_source_raw, threads);
          small_gicp_ms.push_back(small_gicp_run.ms);
        }
      }
    }
    const double carat_median = median(carat_ms), small_gicp_median = median(small_gicp_ms);
    std::printf(
        "%d thread%s: carat %.1f ms (%.1f-%.1f), small_gicp %.1f ms (%.1f-%.1f), "
        "carat / small_gicp = %.3f\n",
        threads, threads == 1 ? "" : "s", carat_median,
        *std::min_element(carat_ms.begin(), carat_ms.end()),
        *std::max_element(carat_ms.begin(), carat_ms.end()), small_gicp_median,
        *std::min_element(small_gicp_ms.begin(), small_gicp_ms.end()),
        *std::max_element(small_gicp_ms.begin(), small_gicp_ms.end()),
        carat_median / small_gicp_median);
    print_pose("carat", carat_run);
    print_pose("small_gicp", small_gicp_run);
    const Eigen::Isometry3d difference =
        carat_run.T_target_source.inverse() * small_gicp_run.T_target_source;
    std::printf("  difference: %.2f mm, %.4f deg\n", 1e3 * difference.translation().norm(),
                rotation_deg(difference.linear()));
  }
  return 0;
}
