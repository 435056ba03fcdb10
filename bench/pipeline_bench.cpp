// The dense-graph stages on the synthetic world (30 frames, two laps, the demo's sensor and
// 0.5 m voxels), single-threaded, per factor: building a full GICP factor (correspondence
// search + block), compressing it exactly (M = 29) or randomly, and linearizing it full vs
// compressed. The ratio compress / linearize-full says after how many LM iterations the exact
// factor has paid for itself.
#include <benchmark/benchmark.h>
#include <tbb/info.h>

#include <memory>
#include <vector>

#include "benchmark_main.hpp"
#include "carat/coreset/compress.hpp"
#include "carat/registration/correspondences.hpp"
#include "carat/registration/dense_graph.hpp"
#include "carat/registration/frame.hpp"
#include "carat/residuals/gicp_block.hpp"
#include "carat/residuals/lossless_block.hpp"
#include "carat/sim/pipeline.hpp"
#include "carat/solver/se3.hpp"

namespace {

struct Graph {
  std::vector<std::shared_ptr<const carat::Frame>> frames;
  std::vector<Eigen::Isometry3d> poses;
  std::vector<carat::FramePair> pairs;
  std::vector<std::shared_ptr<const carat::GicpBlock>> blocks;  // full, one per pair
  std::vector<std::array<double, 7>> storage;
};

const Graph& graph() {
  static const Graph g = [] {
    Graph out;
    // The dense graph at the ground truth: no drift, no odometry.
    carat::SyntheticPipelineOptions options;
    options.drive.frames = 30;
    options.drift.translation_sigma = 0.0;
    options.drift.rotation_sigma_deg = 0.0;
    options.odometry = false;
    options.threads = tbb::info::default_concurrency();
    carat::SyntheticPipeline pipeline = carat::simulate_pipeline(options);
    out.frames = std::move(pipeline.frames);
    out.poses = std::move(pipeline.T_world_truth);
    out.pairs = std::move(pipeline.pairs);
    for (const auto& p : out.pairs) {
      const auto T = out.poses[p.target].inverse() * out.poses[p.source];
      const auto c =
          carat::find_correspondences(out.frames[p.target]->cloud(), out.frames[p.target]->tree(),
                                      out.frames[p.source]->cloud(), T, 1.0);
      out.blocks.push_back(std::make_shared<const carat::GicpBlock>(c, T));
    }
    out.storage.resize(out.poses.size());
    for (std::size_t i = 0; i < out.poses.size(); ++i)
      carat::se3::to_storage(out.poses[i], out.storage[i].data());
    return out;
  }();
  return g;
}

void set_counters(benchmark::State& state) {
  std::size_t rows = 0;
  for (const auto& b : graph().blocks) rows += static_cast<std::size_t>(b->num_rows());
  state.counters["factors"] = static_cast<double>(graph().blocks.size());
  state.counters["rows_per_factor"] =
      static_cast<double>(rows) / static_cast<double>(graph().blocks.size());
}

/// Linearizes blocks[i] at pair i's poses, pair after pair (blocks parallel to the pairs).
template <class Block>
void linearize_each(benchmark::State& state, const std::vector<std::shared_ptr<Block>>& blocks) {
  const Graph& g = graph();
  std::size_t k = 0;
  Eigen::MatrixXd H(6, 6);
  Eigen::VectorXd b(6);
  for (auto _ : state) {
    const std::size_t i = k++ % g.pairs.size();
    const double* values[2] = {g.storage[g.pairs[i].target].data(),
                               g.storage[g.pairs[i].source].data()};
    H.setZero();
    b.setZero();
    benchmark::DoNotOptimize(blocks[i]->accumulate(values, H, b));
  }
  set_counters(state);
}

/// T_target_source of pair i at the ground-truth poses.
Eigen::Isometry3d relative_pose_of(const Graph& g, std::size_t i) {
  return g.poses[g.pairs[i].target].inverse() * g.poses[g.pairs[i].source];
}

void BM_BuildFullFactor(benchmark::State& state) {
  const Graph& g = graph();
  std::size_t k = 0;
  for (auto _ : state) {
    const auto& p = g.pairs[k++ % g.pairs.size()];
    const auto T = g.poses[p.target].inverse() * g.poses[p.source];
    const auto c =
        carat::find_correspondences(g.frames[p.target]->cloud(), g.frames[p.target]->tree(),
                                    g.frames[p.source]->cloud(), T, 1.0);
    carat::GicpBlock block(c, T);
    benchmark::DoNotOptimize(block.num_rows());
  }
  set_counters(state);
}

void BM_LinearizeFull(benchmark::State& state) { linearize_each(state, graph().blocks); }

void BM_CompressExact(benchmark::State& state) {
  const Graph& g = graph();
  std::size_t k = 0;
  for (auto _ : state) {
    const std::size_t i = k++ % g.pairs.size();
    const double* values[2] = {g.storage[g.pairs[i].target].data(),
                               g.storage[g.pairs[i].source].data()};
    carat::CompressionOptions options;
    options.clusters = static_cast<int>(state.range(0));
    auto compressed = carat::compress(g.blocks[i], values, options);
    benchmark::DoNotOptimize(compressed->num_rows());
  }
  set_counters(state);
}

void BM_CompressRandom(benchmark::State& state) {
  const Graph& g = graph();
  std::size_t k = 0;
  carat::RandomSamplingOptions options;
  options.group_size = 3;
  options.target_rows = 30;
  for (auto _ : state) {
    const std::size_t i = k++ % g.pairs.size();
    auto compressed = carat::compress_random(g.blocks[i], options);
    benchmark::DoNotOptimize(compressed->num_rows());
  }
  set_counters(state);
}

void BM_SummarizeLossless(benchmark::State& state) {
  const Graph& g = graph();
  std::size_t k = 0;
  for (auto _ : state) {
    const std::size_t i = k++ % g.pairs.size();
    auto lossless = carat::make_lossless_block(*g.blocks[i], relative_pose_of(g, i));
    benchmark::DoNotOptimize(lossless->num_rows());
  }
  set_counters(state);
}

void BM_LinearizeLossless(benchmark::State& state) {
  const Graph& g = graph();
  std::vector<std::shared_ptr<const carat::LosslessRegistrationBlock>> lossless;
  for (std::size_t i = 0; i < g.pairs.size(); ++i)
    lossless.push_back(carat::make_lossless_block(*g.blocks[i], relative_pose_of(g, i)));
  linearize_each(state, lossless);
}

void BM_LinearizeExact(benchmark::State& state) {
  const Graph& g = graph();
  std::vector<std::shared_ptr<carat::CompressedBlock>> compressed;
  for (std::size_t i = 0; i < g.pairs.size(); ++i) {
    const double* values[2] = {g.storage[g.pairs[i].target].data(),
                               g.storage[g.pairs[i].source].data()};
    compressed.push_back(carat::compress(g.blocks[i], values));
  }
  linearize_each(state, compressed);
}

BENCHMARK(BM_BuildFullFactor)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_LinearizeFull)->Unit(benchmark::kMicrosecond);
// Argument: K, clusters per Fast-Caratheodory level (64 is the default).
BENCHMARK(BM_CompressExact)->Arg(64)->Arg(96)->Arg(128)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_CompressRandom)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_LinearizeExact)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_SummarizeLossless)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_LinearizeLossless)->Unit(benchmark::kMicrosecond);

}  // namespace

CARAT_BENCHMARK_MAIN()
