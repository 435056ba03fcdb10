// Covariances of compressed problems: exact (coreset) and lossless blocks reproduce their full
// blocks' H at the point of compression, so the marginal covariances there are the full
// problem's, on a generic autodiff block (with and without a robust loss) and on the dense
// registration graph of a synthetic drive.
#include <gtest/gtest.h>

#include <memory>
#include <vector>

#include "carat/coreset/problem_compression.hpp"
#include "carat/registration/dense_graph.hpp"
#include "carat/registration/frame_store.hpp"
#include "carat/registration/global_registration.hpp"
#include "carat/solver/autodiff_block.hpp"
#include "carat/solver/covariance.hpp"
#include "carat/solver/loss_function.hpp"
#include "covariance_test_support.hpp"
#include "curve_fit_problem.hpp"
#include "registration_test_drive.hpp"

namespace carat {
namespace {

using test::relative_error;

/// The curve y = exp(m x + d) with its offset d in a variable of its own.
struct Shifted {
  template <typename T>
  bool operator()(const Eigen::Vector2d& xy, const T* mc, const T* d, T* residual) const {
    const T offset[2] = {mc[0], d[0]};
    return test::ExpResidual{}(xy, offset, residual);
  }
};

/// y = exp(m x + c) (2,000 rows over (m, c)) and y = exp(m x + d) (2,000 more over (m, d)):
/// two blocks sharing m, with `loss` on each.
Problem two_curves(std::shared_ptr<const LossFunction> loss) {
  Problem problem;
  const VariableId mc = problem.add_euclidean(Eigen::Vector2d(0.25, 0.05));
  const VariableId d = problem.add_euclidean(Eigen::VectorXd::Constant(1, 0.2));
  problem.add_residual_block(
      make_autodiff_block<1, VariableSize<2>>(test::ExpResidual{}, test::curve_data(2000, 1)), {mc},
      loss);
  problem.add_residual_block(make_autodiff_block<1, VariableSize<2>, VariableSize<1>>(
                                 Shifted{}, test::curve_data(2000, 2)),
                             {mc, d}, loss);
  return problem;
}

void expect_same_covariances(const Problem& compressed, const Problem& full) {
  const Covariance a(compressed);
  const Covariance b(full);
  for (int u = 0; u < full.num_variables(); ++u) {
    for (int v = 0; v < full.num_variables(); ++v) {
      if (full.is_constant(VariableId{u}) || full.is_constant(VariableId{v})) continue;
      const Eigen::MatrixXd expected = b.block(VariableId{u}, VariableId{v});
      const double scale = std::sqrt(b.block(VariableId{u}).norm() * b.block(VariableId{v}).norm());
      ASSERT_LE((a.block(VariableId{u}, VariableId{v}) - expected).norm(), 1e-10 * scale)
          << "variables " << u << ", " << v;
    }
  }
}

TEST(CompressedCovarianceTest, GenericBlocksGiveTheFullProblemsCovariance) {
  for (const auto& loss : std::vector<std::shared_ptr<const LossFunction>>{
           nullptr, std::make_shared<CauchyLoss>(5.0)}) {
    const Problem full = two_curves(loss);
    Problem compressed = two_curves(loss);
    const ProblemCompressionReport report = compress_problem(compressed);
    ASSERT_EQ(report.compressed_blocks, 2);
    EXPECT_LT(report.rows_after, 30u);
    expect_same_covariances(compressed, full);
  }
}

TEST(CompressedCovarianceTest, RegistrationGraphGivesTheFullProblemsCovariance) {
  // 16 frames over two laps; the dense graph of every overlapping pair at the drifting guess.
  const SyntheticPipeline drive = test::simulate_test_drive(
      5, 16, 2, {.seed = 2, .translation_sigma = 0.005, .rotation_sigma_deg = 0.03});
  FrameStore frames(drive.frames);
  const std::vector<FramePair> pairs = build_dense_graph(frames, drive.T_world_drift);
  GlobalRegistrationOptions options;
  options.num_threads = 2;
  options.sampling = ResidualSampling::kFull;
  const RegistrationProblem full =
      build_registration_problem(frames, pairs, drive.T_world_drift, options);
  for (const ResidualSampling sampling : {ResidualSampling::kExact, ResidualSampling::kLossless}) {
    options.sampling = sampling;
    const RegistrationProblem kept =
        build_registration_problem(frames, pairs, drive.T_world_drift, options);
    EXPECT_LT(kept.stats.residual_bytes * 10, full.stats.residual_bytes) << to_string(sampling);
    expect_same_covariances(kept.problem, full.problem);
  }
}

}  // namespace
}  // namespace carat
