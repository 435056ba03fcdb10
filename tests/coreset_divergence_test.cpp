// The information KL divergence behind the paper's Table II.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/LU>
#include <cmath>

#include "carat/base/error.hpp"
#include "carat/coreset/information_divergence.hpp"

namespace carat {
namespace {

Eigen::MatrixXd random_spd(int d, unsigned seed) {
  std::srand(seed);
  const Eigen::MatrixXd L = Eigen::MatrixXd::Random(d, d);
  return L * L.transpose() + 0.5 * Eigen::MatrixXd::Identity(d, d);
}

TEST(InformationDivergenceTest, ZeroForEqualMatrices) {
  const Eigen::MatrixXd H = random_spd(6, 1);
  EXPECT_EQ(information_kld(H, H), 0.0);
  EXPECT_EQ(normalized_information_kld(H, H), 0.0);
}

TEST(InformationDivergenceTest, KnownAnswers) {
  // H~ = s H in d dimensions: KL = d/2 (s - 1 - log s).
  const Eigen::MatrixXd H = random_spd(6, 2);
  for (double s : {0.5, 2.0, 10.0}) {
    const double expected = 3.0 * (s - 1.0 - std::log(s));
    EXPECT_NEAR(information_kld(H, s * H), expected, 1e-12 * expected);
    EXPECT_NEAR(normalized_information_kld(H, s * H), 1.0 - std::exp(-expected), 1e-12);
  }
  // Against the closed form 1/2 (log(|H|/|H~|) + tr(H^-1 H~) - d) on unrelated matrices.
  const Eigen::MatrixXd A = random_spd(6, 3), B = random_spd(6, 4);
  const double closed =
      0.5 * (std::log(A.determinant() / B.determinant()) + (A.inverse() * B).trace() - 6.0);
  EXPECT_NEAR(information_kld(A, B), closed, 1e-10 * std::abs(closed));
  // A tiny perturbation gives a tiny, non-negative divergence (second order in its size).
  Eigen::MatrixXd E = Eigen::MatrixXd::Zero(6, 6);
  E(2, 2) = 1e-9 * A(2, 2);
  const double tiny = information_kld(A, A + E);
  EXPECT_GT(tiny, 0.0);
  EXPECT_LT(tiny, 1e-16);
}

TEST(InformationDivergenceTest, RejectsBadInput) {
  const Eigen::MatrixXd H = random_spd(6, 5);
  EXPECT_THAT([&] { information_kld(H, Eigen::MatrixXd::Identity(5, 5)); },
              ::testing::ThrowsMessage<Error>(::testing::HasSubstr("H is 6 x 6 but H~ is 5 x 5")));
  EXPECT_THAT([&] { information_kld(-H, H); },
              ::testing::ThrowsMessage<Error>(::testing::HasSubstr("H is not positive definite")));
  Eigen::MatrixXd singular = H;
  singular.row(0).setZero();
  singular.col(0).setZero();
  EXPECT_THAT([&] { information_kld(H, singular); },
              ::testing::ThrowsMessage<Error>(::testing::HasSubstr("H~ is not positive definite")));
  Eigen::MatrixXd nan = H;
  nan(1, 1) = std::nan("");
  EXPECT_THROW(information_kld(H, nan), Error);
}

}  // namespace
}  // namespace carat
