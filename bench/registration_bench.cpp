// Per-scan registration time on the real KITTI 00 pair (skipped when ../shared/data is absent):
// preprocess one scan (0.25 m voxels, k-d tree, k = 10 covariances), align 000001 onto 000000
// (GICP, 1 m), and both, with 1 and 2 threads. small_gicp on the same pair, in the same run:
// bench/small_gicp/scan_matching_compare.cpp (docs/benchmarks.md, "Registration").
#include <benchmark/benchmark.h>

#include <filesystem>
#include <memory>

#include "carat/base/blas_kernels.hpp"
#include "carat/registration/align.hpp"
#include "carat/registration/covariance.hpp"
#include "carat/registration/io/kitti_io.hpp"
#include "carat/registration/kdtree.hpp"
#include "carat/registration/voxel_grid.hpp"

namespace {

const std::filesystem::path kDir = std::filesystem::path(CARAT_DATA_DIR) / "kitti00_pair";

struct Scan {
  std::unique_ptr<carat::PointCloud> cloud;
  std::unique_ptr<carat::KdTree> tree;
};

Scan preprocess(const carat::PointCloud& raw, int threads) {
  Scan s{std::make_unique<carat::PointCloud>(carat::voxel_downsample(raw, 0.25, threads)), nullptr};
  s.tree = std::make_unique<carat::KdTree>(*s.cloud);
  carat::CovarianceOptions options;
  options.num_threads = threads;
  carat::estimate_covariances(*s.cloud, *s.tree, options);
  return s;
}

void BM_Preprocess(benchmark::State& state) {
  const auto raw = carat::read_kitti_bin(kDir / "000001.bin", carat::KittiFormat::kXyz);
  for (auto _ : state) {
    Scan s = preprocess(raw, static_cast<int>(state.range(0)));
    benchmark::DoNotOptimize(s.cloud->covariances.data());
  }
}

void BM_Align(benchmark::State& state) {
  const int threads = static_cast<int>(state.range(0));
  const Scan target =
      preprocess(carat::read_kitti_bin(kDir / "000000.bin", carat::KittiFormat::kXyz), threads);
  const Scan source =
      preprocess(carat::read_kitti_bin(kDir / "000001.bin", carat::KittiFormat::kXyz), threads);
  carat::AlignSettings settings;
  settings.num_threads = threads;
  for (auto _ : state) {
    const auto result = carat::align(*target.cloud, *target.tree, *source.cloud,
                                     Eigen::Isometry3d::Identity(), settings);
    benchmark::DoNotOptimize(result.error);
  }
}

void BM_PerScan(benchmark::State& state) {
  const int threads = static_cast<int>(state.range(0));
  const Scan target =
      preprocess(carat::read_kitti_bin(kDir / "000000.bin", carat::KittiFormat::kXyz), threads);
  const auto raw = carat::read_kitti_bin(kDir / "000001.bin", carat::KittiFormat::kXyz);
  carat::AlignSettings settings;
  settings.num_threads = threads;
  for (auto _ : state) {
    const Scan source = preprocess(raw, threads);
    const auto result = carat::align(*target.cloud, *target.tree, *source.cloud,
                                     Eigen::Isometry3d::Identity(), settings);
    benchmark::DoNotOptimize(result.error);
  }
}

}  // namespace

int main(int argc, char** argv) {
  carat::use_cpu_blas_kernels(argv);  // OpenBLAS's kernels for this CPU, as `carat` runs them
  if (std::filesystem::exists(kDir / "000000.bin")) {
    for (auto* fn : {&BM_Preprocess, &BM_Align, &BM_PerScan}) {
      const char* name = fn == &BM_Preprocess ? "BM_Preprocess"
                         : fn == &BM_Align    ? "BM_Align"
                                              : "BM_PerScan";
      benchmark::RegisterBenchmark(name, fn)
          ->Arg(1)
          ->Arg(2)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
    }
  }
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
