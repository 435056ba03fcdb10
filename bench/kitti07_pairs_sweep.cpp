// How far the pairwise registration optimum of each overlapping kitti07_seq5 pair lies from the
// reference relative pose, over registration settings: voxel size, covariance neighbours k,
// maximum correspondence distance, GICP and point-to-plane. Each alignment starts at the
// reference itself, so what it reports is where the pairwise optimum is, not whether it is
// found. Prints one line per setting and, last, the smallest error each pair reached.
// Skips (exit 0) when ../shared/data is absent.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "carat/base/blas_kernels.hpp"
#include "carat/registration/align.hpp"
#include "carat/registration/covariance.hpp"
#include "carat/registration/io/kitti_io.hpp"
#include "carat/registration/io/trajectory_io.hpp"
#include "carat/registration/kdtree.hpp"
#include "carat/registration/voxel_grid.hpp"
#include "carat/solver/se3.hpp"

namespace {

const std::filesystem::path kDir = std::filesystem::path(CARAT_DATA_DIR) / "kitti07_seq5";

}  // namespace

int main(int, char** argv) {
  carat::use_cpu_blas_kernels(argv);  // OpenBLAS's kernels for this CPU, as `carat` runs them
  if (!std::filesystem::exists(kDir / "graph.txt")) {
    std::printf("kitti07_pairs_sweep: %s is absent; skipped\n", kDir.c_str());
    return 0;
  }
  const auto reference =
      carat::read_trajectory(kDir / "graph.txt", carat::TrajectoryFormat::kGraph).poses;
  std::vector<carat::PointCloud> raw;
  for (int i = 0; i < 5; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d/points.bin", i);
    raw.push_back(carat::read_kitti_bin(kDir / name, carat::KittiFormat::kXyz));
  }
  // The pairs with overlap >= 0.2 (data README): every pair at most two frames apart.
  const int pairs[][2] = {{0, 1}, {0, 2}, {1, 2}, {1, 3}, {2, 3}, {2, 4}, {3, 4}};
  constexpr int kPairs = 7;
  double best_m[kPairs], best_deg[kPairs];
  std::fill(best_m, best_m + kPairs, 1e9);
  std::fill(best_deg, best_deg + kPairs, 1e9);
  for (double voxel : {0.1, 0.25, 0.5}) {
    for (int k : {5, 10, 20}) {
      std::vector<std::unique_ptr<carat::PointCloud>> clouds;
      std::vector<std::unique_ptr<carat::KdTree>> trees;
      for (const auto& r : raw) {
        clouds.push_back(std::make_unique<carat::PointCloud>(carat::voxel_downsample(r, voxel)));
        trees.push_back(std::make_unique<carat::KdTree>(*clouds.back()));
        carat::CovarianceOptions options;
        options.neighbors = k;
        carat::estimate_covariances(*clouds.back(), *trees.back(), options);
      }
      for (double max_distance : {0.5, 1.0, 2.0}) {
        for (auto method :
             {carat::RegistrationMethod::kGicp, carat::RegistrationMethod::kPointToPlane}) {
          std::printf("voxel %.2f k %2d max %.1f %-5s", voxel, k, max_distance,
                      method == carat::RegistrationMethod::kGicp ? "gicp" : "p2pl");
          for (int p = 0; p < kPairs; ++p) {
            const int i = pairs[p][0], j = pairs[p][1];
            const Eigen::Isometry3d T_ij = reference[static_cast<std::size_t>(i)].inverse() *
                                           reference[static_cast<std::size_t>(j)];
            carat::AlignSettings settings;
            settings.method = method;
            settings.max_correspondence_distance = max_distance;
            settings.max_iterations = 60;
            settings.num_threads = 2;
            const auto result = carat::align(*clouds[static_cast<std::size_t>(i)],
                                             *trees[static_cast<std::size_t>(i)],
                                             *clouds[static_cast<std::size_t>(j)], T_ij, settings);
            const carat::se3::Vector6d e = carat::se3::log(T_ij.inverse() * result.T_target_source);
            const double m = e.tail<3>().norm(), deg = e.head<3>().norm() * 180.0 / M_PI;
            best_m[p] = std::min(best_m[p], m);
            best_deg[p] = std::min(best_deg[p], deg);
            std::printf("  %d-%d %4.1f cm %.3f deg", i, j, 100.0 * m, deg);
          }
          std::printf("\n");
        }
      }
    }
  }
  std::printf("smallest over all settings:");
  for (int p = 0; p < kPairs; ++p) {
    std::printf("  %d-%d %4.1f cm %.3f deg", pairs[p][0], pairs[p][1], 100.0 * best_m[p],
                best_deg[p]);
  }
  std::printf("\n");
  return 0;
}
