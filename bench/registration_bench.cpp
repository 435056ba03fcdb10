// Per-scan registration time on the real KITTI 00 pair (skipped when ../shared/data is absent):
// preprocess one scan (0.25 m voxels, k-d tree, k = 10 covariances), align 000001 onto 000000
// (GICP, 1 m), and both, with 1 and 2 threads. small_gicp on the same pair, in the same run:
// bench/small_gicp/scan_matching_compare.cpp (docs/benchmarks.md, "Registration"). Then the
// factor build's nearest search, one thread: 000001's points in 000000's tree within 1 m, one
// query at a time against runs of 512 (each search starting where the one before ended).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <filesystem>
#include <memory>
#include <span>
#include <vector>

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

/// 000001's points as queries in 000000's tree, at the identity (the pair is 0.9 m apart).
struct QueryPair {
  Scan target;
  std::vector<Eigen::Vector3f> queries;
  QueryPair()
      : target(
            preprocess(carat::read_kitti_bin(kDir / "000000.bin", carat::KittiFormat::kXyz), 1)) {
    queries = preprocess(carat::read_kitti_bin(kDir / "000001.bin", carat::KittiFormat::kXyz), 1)
                  .cloud->points;
  }
};

void BM_NearestOneAtATime(benchmark::State& state) {
  const QueryPair pair;
  std::size_t found = 0;
  for (auto _ : state) {
    found = 0;
    for (const Eigen::Vector3f& q : pair.queries) {
      std::uint32_t index = 0;
      float sq = 0.0f;
      found += pair.target.tree->nearest_within(q, 1.0f, &index, &sq) ? 1 : 0;
    }
    benchmark::DoNotOptimize(found);
  }
  state.counters["found"] = static_cast<double>(found);
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(pair.queries.size()));
}

void BM_NearestInRuns(benchmark::State& state) {
  const QueryPair pair;
  constexpr std::size_t kRun = 512;  // as find_nearest_pairs()
  std::vector<std::uint32_t> indices(pair.queries.size());
  std::vector<float> distances(pair.queries.size());
  std::size_t found = 0;
  for (auto _ : state) {
    for (std::size_t begin = 0; begin < pair.queries.size(); begin += kRun) {
      const std::size_t n = std::min(kRun, pair.queries.size() - begin);
      pair.target.tree->nearest_within(std::span(pair.queries.data() + begin, n), 1.0f,
                                       indices.data() + begin, distances.data() + begin);
    }
    found =
        static_cast<std::size_t>(std::count_if(indices.begin(), indices.end(), [](std::uint32_t i) {
          return i != carat::KdTree::kNotFound;
        }));
    benchmark::DoNotOptimize(found);
  }
  state.counters["found"] = static_cast<double>(found);
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(pair.queries.size()));
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
    benchmark::RegisterBenchmark("BM_NearestOneAtATime", &BM_NearestOneAtATime)
        ->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark("BM_NearestInRuns", &BM_NearestInRuns)
        ->Unit(benchmark::kMillisecond);
  }
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
