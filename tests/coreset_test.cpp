// The exact coreset: exactness (relative error) over sizes, dimensions, scales and degenerate
// data; output sizes; determinism; the generic Caratheodory; compressed blocks (both poses of
// a binary block exact with 29 rows, re-evaluation at a moved point); random sampling; errors.
#include <gtest/gtest.h>

#include <cmath>
#include <numeric>
#include <random>
#include <tuple>

#include "carat/coreset/caratheodory.hpp"
#include "carat/coreset/compress.hpp"
#include "carat/coreset/quadratic_model.hpp"
#include "carat/coreset/row_coreset.hpp"
#include "carat/solver/error.hpp"
#include "carat/solver/jacobian_checker.hpp"
#include "carat/solver/manifold.hpp"
#include "coreset_test_blocks.hpp"

namespace carat {
namespace {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

struct Rows {
  RowMatrix J;
  Eigen::VectorXd e;
};

Rows random_rows(long n, int d, double scale, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  Rows rows{RowMatrix(n, d), Eigen::VectorXd(n)};
  for (long i = 0; i < rows.J.size(); ++i) rows.J.data()[i] = scale * normal(rng);
  for (long i = 0; i < n; ++i) rows.e[i] = scale * normal(rng);
  return rows;
}

QuadraticModelError coreset_error(const Rows& rows, const RowCoreset& coreset) {
  return relative_error(quadratic_model(rows.J, rows.e),
                        quadratic_model(rows.J, rows.e, coreset.rows, coreset.weights));
}

// (N, M (0 = minimum), K, D, scale, seed)
using Case = std::tuple<long, int, int, int, double, std::uint64_t>;
class CoresetProperty : public ::testing::TestWithParam<Case> {};

TEST_P(CoresetProperty, ExactAndOfTheRequestedSize) {
  const auto [n, target, clusters, dim, scale, seed] = GetParam();
  const Rows rows = random_rows(n, dim, scale, seed);
  RowCoresetOptions options;
  options.target_rows = target;
  options.clusters = clusters;
  options.seed = seed;
  const RowCoreset coreset = select_coreset_rows(rows.J, rows.e, options);
  const long m = target == 0 ? minimum_coreset_rows(dim) : target;
  EXPECT_EQ(static_cast<long>(coreset.rows.size()), std::min(n, m));
  EXPECT_TRUE(std::is_sorted(coreset.rows.begin(), coreset.rows.end()));
  for (double w : coreset.weights) EXPECT_GT(w, 0.0);
  const QuadraticModelError err = coreset_error(rows, coreset);
  EXPECT_LE(err.H, 1e-12);
  EXPECT_LE(err.b, 1e-12);
  EXPECT_LE(err.c, 1e-12);
  // No weight mass is lost: the weights sum to N.
  const double mass = std::accumulate(coreset.weights.begin(), coreset.weights.end(), 0.0);
  EXPECT_NEAR(mass, static_cast<double>(n), 1e-9 * static_cast<double>(n));
}

INSTANTIATE_TEST_SUITE_P(
    Sizes, CoresetProperty,
    ::testing::Values(Case{29, 0, 64, 6, 1.0, 1}, Case{30, 0, 64, 6, 1.0, 2},
                      Case{100, 0, 64, 6, 1.0, 3}, Case{1000, 0, 64, 6, 1.0, 4},
                      Case{30000, 0, 64, 6, 1.0, 5}, Case{30000, 64, 64, 6, 1.0, 6},
                      Case{30000, 256, 64, 6, 1.0, 7}, Case{30000, 1024, 64, 6, 1.0, 8},
                      Case{20000, 0, 40, 6, 1.0, 9}, Case{30000, 0, 64, 6, 1e-6, 10},
                      Case{30000, 0, 64, 6, 1e6, 11}, Case{5000, 0, 128, 12, 1.0, 12},
                      Case{5000, 200, 128, 12, 1e3, 13}, Case{3000, 0, 16, 2, 1.0, 14},
                      Case{1000000, 0, 64, 6, 1.0, 15}));

TEST(CoresetTest, DegenerateData) {
  // Rank-deficient J (a repeated column and a zero column), e = 0, and outliers.
  Rows rows = random_rows(20000, 6, 1.0, 21);
  rows.J.col(3) = rows.J.col(1);
  rows.J.col(5).setZero();
  for (bool zero_e : {false, true}) {
    Rows data = rows;
    if (zero_e) data.e.setZero();
    const RowCoreset coreset = select_coreset_rows(data.J, data.e);
    EXPECT_EQ(coreset.rows.size(), 29u) << "exact size even when fewer rows would do";
    const QuadraticModelError err = coreset_error(data, coreset);
    EXPECT_LE(err.max(), 1e-12) << "zero_e=" << zero_e;
    if (zero_e) {
      RowCoresetOptions loose;
      loose.exact_size = false;
      const RowCoreset small = select_coreset_rows(data.J, data.e, loose);
      EXPECT_LE(small.rows.size(), 29u);
      EXPECT_LE(coreset_error(data, small).max(), 1e-12);
    }
  }
  Rows outliers = random_rows(20000, 6, 1.0, 22);
  for (int k = 0; k < 20; ++k) {
    outliers.J.row(k * 997) *= 1e5;
    outliers.e[k * 991] = 1e6;
  }
  EXPECT_LE(coreset_error(outliers, select_coreset_rows(outliers.J, outliers.e)).max(), 1e-12);
}

TEST(CoresetTest, FewRowsComeBackWhole) {
  const Rows rows = random_rows(20, 6, 1.0, 3);
  const RowCoreset coreset = select_coreset_rows(rows.J, rows.e);
  ASSERT_EQ(coreset.rows.size(), 20u);
  for (std::size_t k = 0; k < 20; ++k) {
    EXPECT_EQ(coreset.rows[k], static_cast<int>(k));
    EXPECT_EQ(coreset.weights[k], 1.0);
  }
}

TEST(CoresetTest, SameSeedSameResult) {
  const Rows rows = random_rows(30000, 6, 1.0, 4);
  RowCoresetOptions options;
  options.seed = 77;
  const RowCoreset a = select_coreset_rows(rows.J, rows.e, options);
  const RowCoreset b = select_coreset_rows(rows.J, rows.e, options);
  EXPECT_EQ(a.rows, b.rows);
  EXPECT_EQ(a.weights, b.weights);
  options.seed = 78;
  const RowCoreset c = select_coreset_rows(rows.J, rows.e, options);
  EXPECT_NE(a.rows, c.rows);
  EXPECT_LE(coreset_error(rows, c).max(), 1e-12);
}

void expect_error(const std::function<void()>& f, const std::string& message) {
  try {
    f();
    FAIL() << "expected: " << message;
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), message);
  }
}

TEST(CoresetTest, BadInputIsAClearError) {
  Rows rows = random_rows(500, 6, 1.0, 5);
  RowCoresetOptions options;
  options.target_rows = 20;
  expect_error([&] { select_coreset_rows(rows.J, rows.e, options); },
               "coreset: target of 20 rows is below the minimum of 29 for reduced dimension 6");
  options = {};
  options.clusters = 20;
  expect_error([&] { select_coreset_rows(rows.J, rows.e, options); },
               "coreset: 20 clusters cannot make progress for reduced dimension 6 (lifted "
               "dimension 28); use at least 30");
  rows.J(123, 2) = std::nan("");
  expect_error([&] { select_coreset_rows(rows.J, rows.e); },
               "coreset: row 123 has a non-finite residual or Jacobian entry");
  rows.J(123, 2) = 0.0;
  rows.e[400] = std::numeric_limits<double>::infinity();
  expect_error([&] { select_coreset_rows(rows.J, rows.e); },
               "coreset: row 400 has a non-finite residual or Jacobian entry");
  const Eigen::VectorXd short_e = Eigen::VectorXd::Zero(10);
  expect_error([&] { select_coreset_rows(rows.J, short_e); },
               "coreset: 500 Jacobian rows but 10 residuals");
}

TEST(CaratheodoryTest, KeepsTheWeightedSumWithAtMostLPlusOnePoints) {
  std::mt19937_64 rng(8);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> uniform(0.1, 2.0);
  for (int n : {10, 64, 5000}) {
    Eigen::MatrixXd P(7, n);
    std::vector<double> w(static_cast<std::size_t>(n));
    for (long i = 0; i < P.size(); ++i) P.data()[i] = normal(rng);
    for (double& x : w) x = uniform(rng);
    const Eigen::Map<const Eigen::VectorXd> wv(w.data(), n);
    const Eigen::VectorXd sum = P * wv;
    CaratheodoryOptions options;
    options.clusters = 16;
    const WeightedSubset s = n <= 64 ? caratheodory(P, w) : fast_caratheodory(P, w, options);
    EXPECT_LE(s.indices.size(), 8u);
    Eigen::VectorXd approx = Eigen::VectorXd::Zero(7);
    double mass = 0.0;
    for (std::size_t k = 0; k < s.indices.size(); ++k) {
      EXPECT_GT(s.weights[k], 0.0);
      approx += s.weights[k] * P.col(s.indices[k]);
      mass += s.weights[k];
    }
    EXPECT_LT((approx - sum).norm(), 1e-12 * sum.norm() + 1e-12) << n;
    EXPECT_NEAR(mass, wv.sum(), 1e-12 * wv.sum());
  }
  Eigen::MatrixXd P = Eigen::MatrixXd::Ones(3, 4);
  expect_error(
      [&] {
        caratheodory(P, std::vector<double>{1, -1, 1, 1});
      },
      "caratheodory: weight 1 is -1.000000; weights must be finite and > 0");
  CaratheodoryOptions few;
  few.clusters = 4;
  expect_error(
      [&] {
        fast_caratheodory(P, std::vector<double>{1, 1, 1, 1}, few);
      },
      "fast_caratheodory: 4 clusters cannot make progress in dimension 3; use at least 5");
}

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
}

}  // namespace
}  // namespace carat
