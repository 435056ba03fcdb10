// A residual written once and differentiated automatically against carat's hand-written block:
// the GICP row r = W (mu_target - T_ij mu_source) as a RelativePoseAutoDiffBlock functor (Eigen's
// AutoDiffScalar, 6 derivatives) beside GicpBlock, on the same 10,000 correspondences, per row:
//   BM_GicpRows/analytic|autodiff     evaluate_rows() of every row with Jacobians
//   BM_GicpAccumulate/analytic|...    accumulate() (H, b, c; GicpBlock has a fused fast path)
//   BM_GicpCompress/analytic|...      compress() to 29 rows (evaluates every row once)
//   BM_CurvePass/<pass>                the passes of a solve over a block of 10^6 rows (the curve
//                                      fit): a linearization, a cost evaluation, the rows with
//                                      Jacobians, a compression
//
//   ./build/bench/autodiff_bench
// Compare the two arguments of one benchmark in the same run (items_per_second is rows / s).
#include <benchmark/benchmark.h>

#include <Eigen/Cholesky>
#include <memory>
#include <numeric>
#include <random>
#include <vector>

#include "../tests/curve_fit_problem.hpp"
#include "benchmark_main.hpp"
#include "carat/coreset/compress.hpp"
#include "carat/residuals/gicp_block.hpp"
#include "carat/residuals/relative_pose_autodiff_block.hpp"
#include "carat/solver/autodiff_block.hpp"
#include "carat/solver/se3.hpp"

namespace {

struct GicpDatum {
  Eigen::Vector3d target, source;
  Eigen::Matrix3d W;  // upper triangular, W^T W = fused covariance^-1
};

struct GicpFunctor {
  template <typename T>
  bool operator()(const GicpDatum& d, const carat::lie::Pose<T>& T_ij, T* residuals) const {
    // Data stay doubles: only T_ij carries derivatives.
    const Eigen::Matrix<T, 3, 1> q = T_ij.act(d.source);
    const T e0 = d.target[0] - q[0], e1 = d.target[1] - q[1], e2 = d.target[2] - q[2];
    residuals[0] = d.W(0, 0) * e0 + d.W(0, 1) * e1 + d.W(0, 2) * e2;
    residuals[1] = d.W(1, 1) * e1 + d.W(1, 2) * e2;
    residuals[2] = d.W(2, 2) * e2;
    return true;
  }
};

struct Fixture {
  std::shared_ptr<const carat::ResidualBlock> analytic, autodiff;
  std::array<double, 7> xi{}, xj{};
  int rows = 0;
};

const Fixture& fixture() {
  static const Fixture f = [] {
    std::mt19937_64 rng(42);
    std::normal_distribution<double> n;
    carat::se3::Vector6d t;
    t << 0.1, -0.05, 0.2, 1.0, 0.5, -0.3;
    const Eigen::Isometry3d T_ij = carat::se3::exp(t);
    std::vector<carat::GicpCorrespondence> correspondences;
    std::vector<GicpDatum> data;
    for (int k = 0; k < 10000; ++k) {
      Eigen::Matrix3d A, B;
      for (int i = 0; i < 9; ++i) {
        A.data()[i] = n(rng);
        B.data()[i] = n(rng);
      }
      const carat::GicpCorrespondence c{Eigen::Vector3d(n(rng), n(rng), n(rng)) * 10,
                                        A * A.transpose() + 0.01 * Eigen::Matrix3d::Identity(),
                                        Eigen::Vector3d(n(rng), n(rng), n(rng)) * 10,
                                        B * B.transpose() + 0.01 * Eigen::Matrix3d::Identity()};
      correspondences.push_back(c);
      const Eigen::Matrix3d fused =
          c.covariance_target + T_ij.linear() * c.covariance_source * T_ij.linear().transpose();
      data.push_back(
          {c.mean_target, c.mean_source, Eigen::LLT<Eigen::Matrix3d>(fused.inverse()).matrixU()});
    }
    Fixture out;
    out.analytic = std::make_shared<carat::GicpBlock>(correspondences, T_ij);
    out.autodiff = carat::make_relative_pose_block<3>(GicpFunctor{}, data);
    carat::se3::to_storage(Eigen::Isometry3d::Identity(), out.xi.data());
    carat::se3::to_storage(T_ij, out.xj.data());
    out.rows = out.analytic->num_rows();
    return out;
  }();
  return f;
}

const carat::ResidualBlock& block(const benchmark::State& state) {
  return state.range(0) == 0 ? *fixture().analytic : *fixture().autodiff;
}

void BM_GicpRows(benchmark::State& state) {
  const Fixture& f = fixture();
  const double* params[2] = {f.xi.data(), f.xj.data()};
  std::vector<int> rows(static_cast<std::size_t>(f.rows));
  std::iota(rows.begin(), rows.end(), 0);
  std::vector<double> residuals(rows.size()), jacobian(rows.size() * 6);
  for (auto _ : state) {
    block(state).evaluate_rows(params, rows, residuals.data(), jacobian.data());
    benchmark::DoNotOptimize(jacobian.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * f.rows);
  state.SetLabel(state.range(0) == 0 ? "analytic" : "autodiff");
}

void BM_GicpAccumulate(benchmark::State& state) {
  const Fixture& f = fixture();
  const double* params[2] = {f.xi.data(), f.xj.data()};
  Eigen::MatrixXd H(6, 6);
  Eigen::VectorXd b(6);
  for (auto _ : state) {
    H.setZero();
    b.setZero();
    benchmark::DoNotOptimize(block(state).accumulate(params, H, b));
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * f.rows);
  state.SetLabel(state.range(0) == 0 ? "analytic" : "autodiff");
}

void BM_GicpCompress(benchmark::State& state) {
  const Fixture& f = fixture();
  const double* params[2] = {f.xi.data(), f.xj.data()};
  const auto shared = state.range(0) == 0 ? f.analytic : f.autodiff;
  carat::CompressionOptions options;
  for (auto _ : state) {
    ++options.seed;
    benchmark::DoNotOptimize(carat::compress(shared, params, options));
  }
  state.SetItemsProcessed(state.iterations() * f.rows);
  state.SetLabel(state.range(0) == 0 ? "analytic" : "autodiff");
}

/// The passes of a solve over one block of 10^6 rows (the curve fit y = exp(m x + c)):
/// 0 accumulate() (a linearization), 1 squared_norm() (a cost evaluation, doubles), 2
/// evaluate_rows() with Jacobians into a buffer (what a compression reads), 3 compress() (that,
/// then the coreset).
void BM_CurvePass(benchmark::State& state) {
  static const auto curve = carat::make_autodiff_block<1, carat::VariableSize<2>>(
      carat::test::ExpResidual{}, carat::test::curve_data(1000000, 1));
  const Eigen::Vector2d mc(0.25, 0.05);
  const double* params[1] = {mc.data()};
  const int n = curve->num_rows();
  std::vector<int> rows(static_cast<std::size_t>(n));
  std::iota(rows.begin(), rows.end(), 0);
  std::vector<double> residuals(rows.size()), jacobian(rows.size() * 2);
  Eigen::MatrixXd H(2, 2);
  Eigen::VectorXd b(2);
  carat::CompressionOptions options;
  for (auto _ : state) {
    switch (state.range(0)) {
      case 0:
        H.setZero();
        b.setZero();
        benchmark::DoNotOptimize(curve->accumulate(params, H, b));
        break;
      case 1:
        benchmark::DoNotOptimize(curve->squared_norm(params));
        break;
      case 2:
        curve->evaluate_rows(params, rows, residuals.data(), jacobian.data());
        benchmark::DoNotOptimize(jacobian.data());
        break;
      default:
        ++options.seed;
        benchmark::DoNotOptimize(carat::compress(curve, params, options));
    }
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * n);
  constexpr const char* kLabels[] = {"accumulate", "squared_norm", "evaluate_rows", "compress"};
  state.SetLabel(kLabels[state.range(0)]);
}

}  // namespace

BENCHMARK(BM_CurvePass)->DenseRange(0, 3)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_GicpRows)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_GicpAccumulate)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_GicpCompress)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

CARAT_BENCHMARK_MAIN()
