// A robust loss per row group (with_group_loss()): each observation weighted by its own rho, the
// block's H, b, c as the iteratively reweighted rows give them, compression that reproduces them
// exactly, and a solve that shrugs off outliers a plain least-squares block follows.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "carat/coreset/compress.hpp"
#include "carat/coreset/compressed_solve.hpp"
#include "carat/solver/autodiff_block.hpp"
#include "carat/solver/block_checker.hpp"
#include "carat/solver/evaluate.hpp"
#include "carat/solver/loss_function.hpp"
#include "carat/solver/numeric_diff_block.hpp"
#include "carat/solver/solve.hpp"

namespace carat {
namespace {

/// A 2-D point seen at `observed`: residual observed - (model + t), two rows per observation.
struct Sighting {
  Eigen::Vector2d model, observed;
};

struct Shift {
  template <typename T>
  bool operator()(const Sighting& s, const T* t, T* r) const {
    r[0] = s.observed.x() - (s.model.x() + t[0]);
    r[1] = s.observed.y() - (s.model.y() + t[1]);
    return true;
  }
};

/// 400 sightings of a shift (1, -2) with 0.05 noise; every tenth is an outlier moved by (3, 1).
std::vector<Sighting> sightings() {
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n(0.0, 0.05);
  std::vector<Sighting> out;
  for (int k = 0; k < 400; ++k) {
    const Eigen::Vector2d model(std::cos(0.1 * k) * k * 0.01, std::sin(0.1 * k));
    Eigen::Vector2d observed = model + Eigen::Vector2d(1.0, -2.0) + Eigen::Vector2d(n(rng), n(rng));
    if (k % 10 == 0) observed += Eigen::Vector2d(3.0, 1.0);
    out.push_back({model, observed});
  }
  return out;
}

const auto kHuber = std::make_shared<HuberLoss>(0.2);

TEST(GroupLossTest, EachObservationIsWeightedByItsOwnLoss) {
  const auto data = sightings();
  const auto block =
      make_autodiff_block<2, VariableSize<2>>(Shift{}, data)->with_group_loss(kHuber);
  ASSERT_EQ(block->group_loss(), kHuber.get());
  const Eigen::Vector2d t(0.9, -1.9);
  const double* params[] = {t.data()};
  // The contract holds (the Jacobian checked on the plain rows).
  const auto euclid = euclidean_manifold(2);
  const Manifold* manifolds[] = {euclid.get()};
  const BlockCheckReport check = check_residual_block(*block, manifolds, params);
  EXPECT_TRUE(check.ok) << check.summary();
  // So do extracts whose rows end mid-group (with the loss, and without).
  const std::vector<int> rows{5, 2, 3, 100, 101, 7, 799};
  const std::shared_ptr<ResidualBlock> plain =
      make_autodiff_block<2, VariableSize<2>>(Shift{}, data);
  for (const auto& source : {block, plain}) {
    const auto part = source->extract_rows(rows);
    const BlockCheckReport extract = check_residual_block(*part, manifolds, params);
    EXPECT_TRUE(extract.ok) << extract.summary();
  }
  // H, b, c by hand: J_g = -I for every observation.
  Eigen::Matrix2d H_hand = Eigen::Matrix2d::Zero();
  Eigen::Vector2d b_hand = Eigen::Vector2d::Zero();
  double c_hand = 0.0;
  for (const Sighting& s : data) {
    const Eigen::Vector2d r = s.observed - (s.model + t);
    const LossValue v = kHuber->evaluate(r.squaredNorm());
    H_hand += v.rho1 * Eigen::Matrix2d::Identity();
    b_hand += -v.rho1 * r;
    c_hand += v.rho;
  }
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(2, 2);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(2);
  const double c = block->accumulate(params, H, b);
  EXPECT_LT((H - H_hand).norm(), 1e-12 * H_hand.norm());
  EXPECT_LT((b - b_hand).norm(), 1e-12 * b_hand.norm());
  EXPECT_NEAR(c, c_hand, 1e-12 * c_hand);
  EXPECT_NEAR(block->squared_norm(params), c_hand, 1e-12 * c_hand);
  // The same loss on a numerically differentiated block gives the same model.
  const auto numeric =
      make_numeric_diff_block<2, VariableSize<2>>(
          [](const Sighting& s, const double* x, double* r) { return Shift{}(s, x, r); }, data)
          ->with_group_loss(kHuber);
  Eigen::MatrixXd Hn = Eigen::MatrixXd::Zero(2, 2);
  Eigen::VectorXd bn = Eigen::VectorXd::Zero(2);
  EXPECT_NEAR(numeric->accumulate(params, Hn, bn), c_hand, 1e-12 * c_hand);
  EXPECT_LT((Hn - H_hand).norm(), 1e-7 * H_hand.norm());
}

TEST(GroupLossTest, CompressionReproducesTheRobustModelExactly) {
  const auto block =
      make_autodiff_block<2, VariableSize<2>>(Shift{}, sightings())->with_group_loss(kHuber);
  const Eigen::Vector2d t(0.9, -1.9);
  const double* params[] = {t.data()};
  const auto compressed = compress(block, params);
  EXPECT_EQ(compressed->num_rows(), 7);
  EXPECT_EQ(compressed->group_loss(), nullptr);  // the weights are frozen into its rows
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(2, 2), Hc = H;
  Eigen::VectorXd b = Eigen::VectorXd::Zero(2), bc = b;
  const double c = block->accumulate(params, H, b);
  const double cc = compressed->accumulate(params, Hc, bc);
  EXPECT_LT((Hc - H).norm(), 1e-10 * H.norm());
  EXPECT_LT((bc - b).norm(), 1e-10 * b.norm());
  EXPECT_NEAR(cc, c, 1e-10 * c);
  EXPECT_NEAR(compressed->squared_norm(params), c, 1e-10 * c);
}

TEST(GroupLossTest, RobustSolvesIgnoreOutliersCompressedOrNot) {
  const auto data = sightings();
  const auto solve_with = [&](bool robust, CompressionMode mode) {
    Problem problem;
    const VariableId t = problem.add_euclidean(Eigen::Vector2d::Zero());
    const auto block = make_autodiff_block<2, VariableSize<2>>(Shift{}, data);
    if (robust) {
      problem.add_residual_block(block->with_group_loss(kHuber), {t});
    } else {
      problem.add_residual_block(block, {t});
    }
    RecompressedSolveOptions options;
    options.mode = mode;
    options.inner.function_tolerance = 1e-14;
    options.inner.gradient_tolerance = 1e-13;
    const RecompressedSolveSummary s = solve_recompressed(problem, options);
    EXPECT_NE(s.termination, TerminationType::kFailure) << s.brief_report();
    const Eigen::Vector2d result(problem.value(t)[0], problem.value(t)[1]);
    return std::make_pair(result, s.final_cost);
  };
  const Eigen::Vector2d truth(1.0, -2.0);
  const auto [plain, plain_cost] = solve_with(false, CompressionMode::kFull);
  const auto [robust, robust_cost] = solve_with(true, CompressionMode::kFull);
  EXPECT_GT((plain - truth).norm(), 0.25);  // pulled a tenth of the way to (3, 1)
  EXPECT_LT((robust - truth).norm(), 0.03);
  // Compressed solves reach the robust optimum too.
  for (CompressionMode mode : {CompressionMode::kSurrogate, CompressionMode::kRecompress}) {
    const auto [x, cost] = solve_with(true, mode);
    EXPECT_LT((x - robust).norm(), 1e-6) << to_string(mode);
    EXPECT_LE(std::abs(cost - robust_cost), 1e-9 * robust_cost) << to_string(mode);
  }
}

/// A loss that misbehaves beyond s = 1.
class BrokenLoss final : public LossFunction {
 public:
  LossValue evaluate(double s) const override {
    if (s <= 1.0) return {s, 1.0, 0.0};
    return {std::numeric_limits<double>::quiet_NaN(), 1.0, 0.0};
  }
  const char* name() const override { return "broken"; }
};

TEST(GroupLossTest, ALossThatMisbehavesIsNamed) {
  Problem problem;
  const VariableId t = problem.add_euclidean(Eigen::Vector2d::Zero());
  problem.add_residual_block(
      make_autodiff_block<2, VariableSize<2>>(Shift{}, sightings(), {}, "shifts")
          ->with_group_loss(std::make_shared<BrokenLoss>()),
      {t});
  const SolverSummary s = solve(SolverOptions{}, problem);
  EXPECT_EQ(s.termination, TerminationType::kFailure);
  EXPECT_NE(s.message.find("residual block 0 ('shifts')"), std::string::npos) << s.message;
  EXPECT_NE(s.message.find("the group loss 'broken' returned rho = nan"), std::string::npos)
      << s.message;
  const auto block = make_autodiff_block<2, VariableSize<2>>(Shift{}, sightings(), {}, "shifts");
  EXPECT_THROW(block->with_group_loss(nullptr), Error);
}

}  // namespace
}  // namespace carat
