// The generic Caratheodory and Fast-Caratheodory on weighted point sets.
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
#include "carat/solver/jacobian_checker.hpp"
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
  Eigen::MatrixXd bad = Eigen::MatrixXd::Ones(3, 4);
  bad(1, 2) = std::numeric_limits<double>::infinity();
  expect_error(
      [&] {
        caratheodory(bad, std::vector<double>{1, 1, 1, 1});
      },
      "caratheodory: point 2 has a non-finite coordinate");
  expect_error(
      [&] {
        caratheodory(P, std::vector<double>{1, 1, 1});
      },
      "caratheodory: 4 points but 3 weights");
  expect_error(
      [&] {
        fast_caratheodory(P, std::vector<double>{1, 1, 0, 1});
      },
      "fast_caratheodory: weight 2 is 0.000000; weights must be finite and > 0");
}

TEST(CaratheodoryTest, FastCaratheodoryIsDeterministicAndExactOnDegeneratePoints) {
  // Points on a 3-D affine subspace of R^10: at most 4 survive; same seed, same subset.
  std::mt19937_64 rng(9);
  std::normal_distribution<double> normal;
  const Eigen::MatrixXd basis = Eigen::MatrixXd::Random(10, 3);
  Eigen::MatrixXd P(10, 20000);
  for (Eigen::Index i = 0; i < P.cols(); ++i) {
    P.col(i) = basis * Eigen::Vector3d(normal(rng), normal(rng), normal(rng)) +
               Eigen::VectorXd::Constant(10, 5.0);
  }
  const std::vector<double> w(20000, 0.5);
  CaratheodoryOptions options;
  options.seed = 3;
  const WeightedSubset a = fast_caratheodory(P, w, options);
  const WeightedSubset b = fast_caratheodory(P, w, options);
  EXPECT_EQ(a.indices, b.indices);
  EXPECT_EQ(a.weights, b.weights);
  EXPECT_LE(a.indices.size(), 4u);
  Eigen::VectorXd approx = Eigen::VectorXd::Zero(10);
  for (std::size_t k = 0; k < a.indices.size(); ++k) approx += a.weights[k] * P.col(a.indices[k]);
  const Eigen::VectorXd sum = P.rowwise().sum() * 0.5;
  EXPECT_LT((approx - sum).norm(), 1e-12 * sum.norm());
}

}  // namespace
}  // namespace carat
