// Compressed blocks: both poses of a binary block exact with 29 rows, re-evaluation at a moved
// point, random sampling, validation.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <tuple>

#include "carat/base/error.hpp"
#include "carat/coreset/caratheodory.hpp"
#include "carat/coreset/compress.hpp"
#include "carat/coreset/quadratic_model.hpp"
#include "carat/coreset/row_coreset.hpp"
#include "carat/solver/autodiff_block.hpp"
#include "carat/solver/jacobian_checker.hpp"
#include "carat/solver/loss_function.hpp"
#include "carat/solver/manifold.hpp"
#include "coreset_test_blocks.hpp"
#include "coreset_test_support.hpp"

namespace carat {
namespace {

using test::coreset_error;
using test::expect_error;
using test::random_rows;
using test::RowMatrix;
using test::Rows;

/// A random point-to-plane block between two poses and its values.
struct PlaneProblem {
  std::shared_ptr<test::PlaneBlock> block;
  double pose_i[7];
  double pose_j[7];
};

PlaneProblem make_plane_problem(int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  std::vector<Eigen::Vector3d> p, q, nn;
  for (int k = 0; k < n; ++k) {
    p.emplace_back(10 * normal(rng), 10 * normal(rng), 2 * normal(rng));
    q.push_back(p.back() + 0.1 * Eigen::Vector3d(normal(rng), normal(rng), normal(rng)));
    nn.push_back(Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized());
  }
  PlaneProblem out{std::make_shared<test::PlaneBlock>(p, q, nn), {}, {}};
  se3::Vector6d xi;
  for (int k = 0; k < 6; ++k) xi[k] = 0.3 * normal(rng);
  se3::to_storage(se3::exp(xi), out.pose_i);
  for (int k = 0; k < 6; ++k) xi[k] = 0.3 * normal(rng);
  se3::to_storage(se3::exp(xi), out.pose_j);
  return out;
}

TEST(CompressTest, BinaryBlockIsExactForBothPosesWith29Rows) {
  PlaneProblem problem = make_plane_problem(30000, 31);
  const double* params[2] = {problem.pose_i, problem.pose_j};
  // The test block's reduced Jacobian and map are right (numeric check through SE(3) plus).
  {
    PlaneProblem small = make_plane_problem(50, 32);
    const double* small_params[2] = {small.pose_i, small.pose_j};
    const Manifold* manifolds[2] = {se3_manifold().get(), se3_manifold().get()};
    const JacobianCheckResult check = check_jacobians(*small.block, manifolds, small_params);
    ASSERT_TRUE(check.ok) << check.message;
  }
  const std::shared_ptr<CompressedBlock> compressed = compress(problem.block, params);
  EXPECT_EQ(compressed->num_rows(), 29);
  // The compressed block holds only the 29 selected rows' data.
  EXPECT_EQ(compressed->inner().num_rows(), 29);
  EXPECT_LT(compressed->memory_bytes(), problem.block->memory_bytes() / 100);
  Eigen::VectorXd r_full, r_small;
  Eigen::MatrixXd J_full, J_small;
  evaluate_full_jacobian(*problem.block, params, &r_full, &J_full);
  evaluate_full_jacobian(*compressed, params, &r_small, &J_small);
  const Eigen::MatrixXd H = J_full.transpose() * J_full, H_small = J_small.transpose() * J_small;
  const Eigen::VectorXd b = J_full.transpose() * r_full, b_small = J_small.transpose() * r_small;
  EXPECT_EQ(H.rows(), 12);
  EXPECT_LE((H - H_small).norm() / H.norm(), 1e-12);
  EXPECT_LE((b - b_small).norm() / b.norm(), 1e-12);
  EXPECT_LE(std::abs(r_full.squaredNorm() - r_small.squaredNorm()) / r_full.squaredNorm(), 1e-12);
  // Cross terms between the poses (H_ij) are exact too, not just the diagonal blocks.
  EXPECT_LE((H.topRightCorner<6, 6>() - H_small.topRightCorner<6, 6>()).norm() / H.norm(), 1e-12);
}

TEST(CompressTest, ReevaluationAtAMovedPointIsTheWeightedSubset) {
  PlaneProblem problem = make_plane_problem(5000, 41);
  const double* params[2] = {problem.pose_i, problem.pose_j};
  const auto compressed = compress(problem.block, params);
  // Move pose j and evaluate both ways.
  double moved[7];
  const double delta[6] = {0.05, -0.02, 0.03, 0.4, -0.1, 0.2};
  se3_manifold()->plus(problem.pose_j, delta, moved);
  const double* moved_params[2] = {problem.pose_i, moved};
  Eigen::VectorXd r;
  Eigen::MatrixXd J;
  evaluate_full_jacobian(*compressed, moved_params, &r, &J);
  // Direct: the original block's rows, scaled by sqrt(w). The original row index of compressed
  // row k is the k-th selected row (compress() keeps them in ascending order).
  const RowCoreset reference = [&] {
    const int n = problem.block->num_rows();
    RowMatrix Jr(n, 6);
    Eigen::VectorXd e(n);
    std::vector<int> all(static_cast<std::size_t>(n));
    std::iota(all.begin(), all.end(), 0);
    problem.block->evaluate_rows(params, all, e.data(), Jr.data());
    return select_coreset_rows(Jr, e);
  }();
  ASSERT_EQ(reference.rows.size(), static_cast<std::size_t>(compressed->num_rows()));
  Eigen::VectorXd r_direct;
  Eigen::MatrixXd J_direct;
  evaluate_full_jacobian(*problem.block, moved_params, &r_direct, &J_direct);
  for (std::size_t k = 0; k < reference.rows.size(); ++k) {
    const double s = std::sqrt(reference.weights[k]);
    EXPECT_NEAR(r[static_cast<Eigen::Index>(k)], s * r_direct[reference.rows[k]],
                1e-12 * (1 + std::abs(r[static_cast<Eigen::Index>(k)])));
    EXPECT_LT((J.row(static_cast<Eigen::Index>(k)) - s * J_direct.row(reference.rows[k])).norm(),
              1e-11 * (1 + J.row(static_cast<Eigen::Index>(k)).norm()));
  }
}

TEST(CompressTest, RandomSamplingKeepsWholeGroups) {
  PlaneProblem problem = make_plane_problem(3000, 51);
  RandomSamplingOptions options;
  options.target_rows = 30;
  options.group_size = 3;
  const auto sampled = compress_random(problem.block, options);
  EXPECT_EQ(sampled->num_rows(), 30);
  for (double w : sampled->weights()) EXPECT_DOUBLE_EQ(w, 100.0);
  const auto again = compress_random(problem.block, options);
  EXPECT_EQ(std::vector<double>(sampled->weights().begin(), sampled->weights().end()),
            std::vector<double>(again->weights().begin(), again->weights().end()));
  options.target_rows = 31;
  expect_error(
      [&] { compress_random(problem.block, options); },
      "compress_random: target of 31 rows must be a positive multiple of the group size 3");
  options.target_rows = 30;
  options.group_size = 7;
  expect_error([&] { compress_random(problem.block, options); },
               "compress_random: the block's 3000 rows are not a whole number of groups of 7");
}

TEST(CompressTest, CompressedBlockValidatesItsRows) {
  PlaneProblem problem = make_plane_problem(10, 61);
  expect_error(
      [&] {
        CompressedBlock(problem.block, {0, 11}, {1.0, 1.0});
      },
      "CompressedBlock: row 11 is out of range (block has 10 rows)");
  expect_error(
      [&] {
        CompressedBlock(problem.block, {0, 1}, {1.0, 0.0});
      },
      "CompressedBlock: weight 1 is 0.000000; weights must be finite and > 0");
  expect_error(
      [&] {
        CompressedBlock(problem.block, {0, 1}, {1.0});
      },
      "CompressedBlock: 2 rows but 1 weights");
  expect_error([&] { CompressedBlock(std::shared_ptr<const ResidualBlock>()); },
               "CompressedBlock: inner block is null");
  // A block whose rows carry their weights already: every row of it, nothing kept beside.
  const CompressedBlock folded(problem.block);
  EXPECT_TRUE(folded.folded());
  EXPECT_EQ(folded.num_rows(), 10);
  EXPECT_EQ(folded.memory_bytes(), problem.block->memory_bytes());
}

/// A block that cannot extract rows: compression must keep it whole and index into it.
class NoExtractBlock final : public ResidualBlock {
 public:
  explicit NoExtractBlock(std::shared_ptr<const ResidualBlock> inner) : inner_(std::move(inner)) {}
  int num_rows() const override { return inner_->num_rows(); }
  std::span<const int> tangent_dims() const override { return inner_->tangent_dims(); }
  int reduced_dim() const override { return inner_->reduced_dim(); }
  void reduced_map(ParameterPointers params, double* A) const override {
    inner_->reduced_map(params, A);
  }
  void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* residuals,
                     double* jacobian) const override {
    inner_->evaluate_rows(params, rows, residuals, jacobian);
  }
  std::size_t memory_bytes() const override { return inner_->memory_bytes(); }

 private:
  std::shared_ptr<const ResidualBlock> inner_;
};

TEST(CompressTest, BlockWithoutRowExtractionIsIndexedNotCopied) {
  PlaneProblem problem = make_plane_problem(4000, 71);
  const double* params[2] = {problem.pose_i, problem.pose_j};
  const auto plain = std::make_shared<NoExtractBlock>(problem.block);
  const auto indexed = compress(plain, params);
  const auto extracted = compress(problem.block, params);
  ASSERT_EQ(indexed->num_rows(), 29);
  EXPECT_EQ(indexed->inner().num_rows(), 4000) << "kept whole, rows by index";
  EXPECT_EQ(extracted->inner().num_rows(), 29) << "only the selected rows' data";
  EXPECT_GT(indexed->memory_bytes(), extracted->memory_bytes());
  // Same seed, same rows and weights either way; the same rows evaluate identically.
  EXPECT_EQ(std::vector<double>(indexed->weights().begin(), indexed->weights().end()),
            std::vector<double>(extracted->weights().begin(), extracted->weights().end()));
  Eigen::VectorXd r_a, r_b;
  Eigen::MatrixXd J_a, J_b;
  evaluate_full_jacobian(*indexed, params, &r_a, &J_a);
  evaluate_full_jacobian(*extracted, params, &r_b, &J_b);
  EXPECT_EQ(r_a, r_b);
  EXPECT_EQ(J_a, J_b);
  // Forwarded reduced structure.
  EXPECT_EQ(indexed->reduced_dim(), 6);
  EXPECT_EQ(indexed->tangent_dim(), 12);
}

// Rows chosen by the caller: each kept row counts its weight times, in the rows' evaluation, in
// H, b and c (the block evaluated in one call), and in the cost; rows or weights that do not fit
// are named.
TEST(CompressTest, ChosenRowsCountWithTheirWeights) {
  PlaneProblem problem = make_plane_problem(40, 91);
  const double* params[2] = {problem.pose_i, problem.pose_j};
  const std::vector<int> rows{2, 5, 9, 31};
  const std::vector<double> weights{1.0, 2.0, 4.0, 0.5};
  for (const bool extracts : {true, false}) {
    const std::shared_ptr<const ResidualBlock> block =
        extracts ? std::shared_ptr<const ResidualBlock>(problem.block)
                 : std::make_shared<NoExtractBlock>(problem.block);
    const auto kept = compress_rows(block, rows, weights);
    ASSERT_EQ(kept->num_rows(), 4);
    Eigen::VectorXd r_all, r;
    Eigen::MatrixXd J_all, J;
    evaluate_full_jacobian(*problem.block, params, &r_all, &J_all);
    evaluate_full_jacobian(*kept, params, &r, &J);
    Eigen::MatrixXd H_expected = Eigen::MatrixXd::Zero(J_all.cols(), J_all.cols());
    Eigen::VectorXd b_expected = Eigen::VectorXd::Zero(J_all.cols());
    double c_expected = 0.0;
    for (std::size_t k = 0; k < rows.size(); ++k) {
      const auto i = static_cast<Eigen::Index>(rows[k]);
      const double s = std::sqrt(weights[k]);
      EXPECT_NEAR(r[static_cast<Eigen::Index>(k)], s * r_all[i], 1e-12 * (1 + std::abs(r_all[i])));
      H_expected += weights[k] * J_all.row(i).transpose() * J_all.row(i);
      b_expected += weights[k] * J_all.row(i).transpose() * r_all[i];
      c_expected += weights[k] * r_all[i] * r_all[i];
    }
    const int D = kept->reduced_dim();
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(D, D);
    Eigen::VectorXd b = Eigen::VectorXd::Zero(D);
    const double c = kept->accumulate(params, H, b);
    EXPECT_NEAR(c, c_expected, 1e-12 * c_expected);
    EXPECT_NEAR(kept->squared_norm(params), c_expected, 1e-12 * c_expected);
    // H and b over the reduced coordinates: the full ones mapped through the block's reduced map.
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> A(D, J_all.cols());
    problem.block->reduced_map(params, A.data());
    const Eigen::MatrixXd H_full = A.transpose() * H * A;
    EXPECT_LT((H_full - H_expected).norm(), 1e-10 * H_expected.norm());
    EXPECT_LT((A.transpose() * b - b_expected).norm(), 1e-10 * (1 + b_expected.norm()));
  }
  const struct {
    std::vector<int> rows;
    std::vector<double> weights;
    const char* message;
  } bad[] = {
      {{2, 5}, {1.0}, "compress_rows: 2 rows but 1 weights"},
      {{}, {}, "compress_rows: no rows"},
      {{5, 2}, {1.0, 1.0}, "compress_rows: rows must ascend without repeats; row 2 follows 5"},
      {{5, 5}, {1.0, 1.0}, "compress_rows: rows must ascend without repeats; row 5 follows 5"},
      {{2, 40}, {1.0, 1.0}, "compress_rows: row 40 is out of range (the block has 40 rows)"},
      {{2, 5},
       {1.0, 0.0},
       "compress_rows: the weight of row 5 is 0; weights must be finite and > 0"},
      {{2, 5},
       {1.0, std::numeric_limits<double>::infinity()},
       "compress_rows: the weight of row 5 is inf; weights must be finite and > 0"},
  };
  for (const auto& c : bad) {
    expect_error([&] { compress_rows(problem.block, c.rows, c.weights); }, c.message);
  }
  expect_error([&] { compress_rows(nullptr, {2}, {1.0}); }, "compress_rows: block is null");
  // A loss per row group would be split by a choice of rows.
  const std::vector<Eigen::Vector2d> data{{0.0, 1.0}, {1.0, 2.0}, {2.0, 3.5}};
  const auto robust = make_autodiff_block<1, VariableSize<2>>(
                          [](const Eigen::Vector2d& d, const auto* mc, auto* r) {
                            r[0] = mc[0] * d.x() + mc[1] - d.y();
                            return true;
                          },
                          data)
                          ->with_group_loss(std::make_shared<HuberLoss>(1.0));
  expect_error(
      [&] {
        compress_rows(robust, {0, 2}, {1.5, 1.5});
      },
      "has a loss per row group, which a choice of rows would split");
}

TEST(CompressTest, FewRowsAndBadOptions) {
  PlaneProblem problem = make_plane_problem(20, 81);
  const double* params[2] = {problem.pose_i, problem.pose_j};
  const auto whole = compress(problem.block, params);
  ASSERT_EQ(whole->num_rows(), 20);
  for (double w : whole->weights()) EXPECT_EQ(w, 1.0);
  CompressionOptions options;
  options.target_rows = 28;
  expect_error([&] { compress(problem.block, params, options); },
               "coreset: target of 28 rows is below the minimum of 29 for reduced dimension 6");
  options = {};
  options.clusters = 29;
  expect_error([&] { compress(problem.block, params, options); }, "use at least 30");
  const double* one_param[1] = {problem.pose_i};
  expect_error([&] { compress(problem.block, one_param); },
               "compress: the block has 2 variables but 1 values were given");
}

}  // namespace
}  // namespace carat
