// The GICP block: numeric Jacobians for both poses, the fast path against extracted rows,
// weighted extracts, whole correspondences and bad input.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/residuals/gicp_block.hpp"
#include "carat/solver/jacobian_checker.hpp"
#include "carat/solver/manifold.hpp"
#include "carat/solver/se3.hpp"
#include "test_support.hpp"

namespace carat {
namespace {

std::vector<GicpCorrespondence> random_correspondences(int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  std::vector<GicpCorrespondence> out;
  for (int k = 0; k < n; ++k) {
    Eigen::Matrix3d A, B;
    for (int i = 0; i < 9; ++i) {
      A.data()[i] = normal(rng);
      B.data()[i] = normal(rng);
    }
    out.push_back({Eigen::Vector3d(normal(rng), normal(rng), normal(rng)) * 5,
                   A * A.transpose() + 0.01 * Eigen::Matrix3d::Identity(),
                   Eigen::Vector3d(normal(rng), normal(rng), normal(rng)) * 5,
                   B * B.transpose() + 0.01 * Eigen::Matrix3d::Identity()});
  }
  return out;
}

TEST(GicpBlockTest, JacobiansMatchNumericForBothPoses) {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> normal;
  const Manifold* manifolds[2] = {se3_manifold().get(), se3_manifold().get()};
  for (int trial = 0; trial < 5; ++trial) {
    se3::Vector6d a, b;
    for (int i = 0; i < 6; ++i) {
      a[i] = (trial == 0 ? 0.0 : 0.5) * normal(rng);
      b[i] = (trial == 0 ? 0.0 : 0.5) * normal(rng);
    }
    double pose_i[7], pose_j[7];
    se3::to_storage(se3::exp(a), pose_i);
    se3::to_storage(se3::exp(b), pose_j);
    const double* params[2] = {pose_i, pose_j};
    const GicpBlock block(random_correspondences(20, static_cast<std::uint64_t>(trial)),
                          se3::exp(a).inverse() * se3::exp(b));
    const JacobianCheckResult result = check_jacobians(block, manifolds, params);
    EXPECT_TRUE(result.ok) << result.message;
  }
}

TEST(GicpBlockTest, FastPathAndExtractedRowsAgree) {
  const auto pairs = random_correspondences(2000, 9);
  double pose_i[7], pose_j[7];
  se3::Vector6d xi;
  xi << 0.1, -0.05, 0.2, 1.0, 0.5, -0.3;
  se3::to_storage(Eigen::Isometry3d::Identity(), pose_i);
  se3::to_storage(se3::exp(xi), pose_j);
  const double* params[2] = {pose_i, pose_j};
  const GicpBlock block(pairs, se3::exp(xi));
  ASSERT_EQ(block.num_rows(), 6000);
  Eigen::MatrixXd H_fast = Eigen::MatrixXd::Zero(6, 6), H_rows = Eigen::MatrixXd::Zero(6, 6);
  Eigen::VectorXd b_fast = Eigen::VectorXd::Zero(6), b_rows = Eigen::VectorXd::Zero(6);
  const double c_fast = block.accumulate(params, H_fast, b_fast);
  const double c_rows = block.ResidualBlock::accumulate(params, H_rows, b_rows);
  EXPECT_LT((H_fast - H_rows).norm(), 1e-9 * H_rows.norm());
  EXPECT_LT((b_fast - b_rows).norm(), 1e-9 * b_rows.norm());
  EXPECT_NEAR(c_fast, c_rows, 1e-9 * c_rows);
  EXPECT_NEAR(block.squared_norm(params), c_rows, 1e-9 * c_rows);
  // Extract rows that split correspondences (1 or 2 of their 3 rows) and compare row by row.
  const std::vector<int> rows = {5, 0, 4, 3000, 5999, 1234, 1235};
  const auto extracted = block.extract_rows(rows);
  ASSERT_EQ(extracted->num_rows(), 7);
  EXPECT_LT(extracted->memory_bytes(), block.memory_bytes() / 100);
  Eigen::VectorXd r1(7), r2(7);
  Eigen::Matrix<double, 7, 6, Eigen::RowMajor> J1, J2;
  block.evaluate_rows(params, rows, r1.data(), J1.data());
  std::vector<int> local(7);
  std::iota(local.begin(), local.end(), 0);
  extracted->evaluate_rows(params, local, r2.data(), J2.data());
  // An extract keeps l . mu_target precomputed per row (7 doubles instead of a correspondence's
  // 12): its residuals agree with the full block's to rounding, not bit for bit.
  for (int k = 0; k < 7; ++k) EXPECT_NEAR(r2[k], r1[k], 1e-14 * (1.0 + std::abs(r1[k]))) << k;
  EXPECT_EQ(J1, J2);
  EXPECT_EQ(extracted->memory_bytes(), 7 * 7 * sizeof(double));
  // Whole correspondences in order stay whole: 12 doubles for their 3 rows, bit-identical rows.
  const std::vector<int> triples = {3, 4, 5, 5997, 5998, 5999};
  const auto whole = block.extract_rows(triples);
  ASSERT_EQ(whole->num_rows(), 6);
  EXPECT_EQ(whole->memory_bytes(), 2 * 12 * sizeof(double));
  Eigen::VectorXd t1(6), t2(6);
  block.evaluate_rows(params, triples, t1.data(), nullptr);
  const std::vector<int> first_six = {0, 1, 2, 3, 4, 5};
  whole->evaluate_rows(params, first_six, t2.data(), nullptr);
  EXPECT_EQ(t1, t2);
}

TEST(GicpBlockTest, WeightedExtractFoldsTheWeightsIntoItsRows) {
  const auto pairs = random_correspondences(500, 12);
  se3::Vector6d xi;
  xi << 0.2, 0.1, -0.1, -0.5, 0.8, 0.3;
  const GicpBlock block(pairs, se3::exp(xi));
  // Evaluated away from where the block was built: the weighted rows are sqrt(w) times the rows
  // at every pose, not only at one.
  double pose_i[7], pose_j[7];
  se3::to_storage(se3::exp(0.3 * xi), pose_i);
  se3::to_storage(se3::exp(-xi), pose_j);
  const double* params[2] = {pose_i, pose_j};
  const std::vector<int> rows = {1, 0, 1499, 700, 700};
  const std::vector<double> weights = {4.0, 0.25, 123.5, 1e-3, 7.0};
  const auto weighted = block.extract_weighted_rows(rows, weights);
  ASSERT_NE(weighted, nullptr);
  ASSERT_EQ(weighted->num_rows(), 5);
  EXPECT_EQ(weighted->memory_bytes(), 5 * 7 * sizeof(double)) << "no weight kept beside a row";
  Eigen::VectorXd r(5), rw(5);
  Eigen::Matrix<double, 5, 6, Eigen::RowMajor> J, Jw;
  block.evaluate_rows(params, rows, r.data(), J.data());
  const std::vector<int> local = {0, 1, 2, 3, 4};
  weighted->evaluate_rows(params, local, rw.data(), Jw.data());
  for (int k = 0; k < 5; ++k) {
    const double s = std::sqrt(weights[static_cast<std::size_t>(k)]);
    EXPECT_NEAR(rw[k], s * r[k], 1e-14 * (1.0 + std::abs(s * r[k]))) << k;
    EXPECT_LT((Jw.row(k) - s * J.row(k)).norm(), 1e-14 * (1.0 + s * J.row(k).norm())) << k;
  }
  // An extract of the weighted rows keeps their weights.
  const std::vector<int> again = {2};
  const auto part = weighted->extract_rows(again);
  double r_part = 0.0;
  part->evaluate_rows(params, std::span<const int>(local.data(), 1), &r_part, nullptr);
  EXPECT_EQ(r_part, rw[2]);
  // Whole correspondences in order are cheaper kept whole with one weight beside each row.
  EXPECT_EQ(block.extract_weighted_rows(std::vector<int>{3, 4, 5}, std::vector<double>{2, 2, 2}),
            nullptr);
  const auto message = [&](const std::vector<int>& selected, const std::vector<double>& w) {
    try {
      block.extract_weighted_rows(selected, w);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message(rows, {1.0}), "GicpBlock: 5 rows but 1 weights");
  EXPECT_EQ(message({0, 1}, {1.0, std::nan("")}),
            "GicpBlock: weight 1 is nan; weights must be finite and > 0");
  EXPECT_EQ(message({0, 1}, {1.0, -2.0}),
            "GicpBlock: weight 1 is -2.000000; weights must be finite and > 0");
}

TEST(GicpBlockTest, WholeCorrespondencesMatchRowByRowEvaluation) {
  // Rows asked for as whole correspondences in order take a straight-line path (runs of eight
  // correspondences at once, then one at a time: 50 is six runs and two more); one row at a time
  // takes the general one. All must give the same bits, Jacobians included.
  const auto pairs = random_correspondences(50, 4);
  se3::Vector6d xi;
  xi << -0.3, 0.2, 0.1, 0.5, -1.0, 0.25;
  double pose_i[7], pose_j[7];
  se3::to_storage(se3::exp(0.5 * xi), pose_i);
  se3::to_storage(se3::exp(xi), pose_j);
  const double* params[2] = {pose_i, pose_j};
  const GicpBlock block(pairs, se3::exp(0.5 * xi).inverse() * se3::exp(xi));
  const int n = block.num_rows();
  std::vector<int> all(static_cast<std::size_t>(n));
  std::iota(all.begin(), all.end(), 0);
  // Also a run that starts mid-correspondence: rows 1..n-1 (the first group is partial).
  for (const int first : {0, 1}) {
    const std::span<const int> rows(all.data() + first, static_cast<std::size_t>(n - first));
    std::vector<double> r_all(rows.size()), J_all(6 * rows.size());
    block.evaluate_rows(params, rows, r_all.data(), J_all.data());
    for (std::size_t k = 0; k < rows.size(); ++k) {
      double r_one = 0.0, J_one[6];
      block.evaluate_rows(params, rows.subspan(k, 1), &r_one, J_one);
      EXPECT_EQ(r_all[k], r_one) << "row " << rows[k];
      for (int j = 0; j < 6; ++j) EXPECT_EQ(J_all[6 * k + static_cast<std::size_t>(j)], J_one[j]);
    }
  }
}

TEST(GicpBlockTest, RejectsBadInput) {
  EXPECT_THROW(GicpBlock({}, Eigen::Isometry3d::Identity()), Error);
  auto pairs = random_correspondences(3, 1);
  pairs[1].mean_source.x() = std::nan("");
  try {
    GicpBlock block(pairs, Eigen::Isometry3d::Identity());
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "GicpBlock: correspondence 1 has a non-finite value");
  }
}

TEST(GicpBlockTest, IndexedFloatCloudsGiveTheSameRows) {
  // Float clouds with covariances as 6 unique entries, and pairs of indices into them.
  std::mt19937_64 rng(11);
  std::normal_distribution<float> normal;
  const auto cloud = [&](int n, std::vector<Eigen::Vector3f>* means,
                         std::vector<Eigen::Matrix<float, 6, 1>>* covariances) {
    for (int k = 0; k < n; ++k) {
      means->emplace_back(5.0f * normal(rng), 5.0f * normal(rng), 5.0f * normal(rng));
      Eigen::Matrix3f A;
      for (int i = 0; i < 9; ++i) A.data()[i] = normal(rng);
      const Eigen::Matrix3f C = A * A.transpose() + 0.01f * Eigen::Matrix3f::Identity();
      Eigen::Matrix<float, 6, 1> c;
      c << C(0, 0), C(0, 1), C(0, 2), C(1, 1), C(1, 2), C(2, 2);
      covariances->push_back(c);
    }
  };
  std::vector<Eigen::Vector3f> target_means, source_means;
  std::vector<Eigen::Matrix<float, 6, 1>> target_covariances, source_covariances;
  cloud(300, &target_means, &target_covariances);
  cloud(2500, &source_means, &source_covariances);
  std::vector<std::array<std::uint32_t, 2>> pairs;
  std::vector<GicpCorrespondence> correspondences;
  const auto as_matrix = [](const Eigen::Matrix<float, 6, 1>& c) {
    Eigen::Matrix3d C;
    C << c[0], c[1], c[2], c[1], c[3], c[4], c[2], c[4], c[5];
    return C;
  };
  for (std::uint32_t s = 0; s < 2500; s += 1 + s % 3) {
    const std::uint32_t t = (7 * s) % 300;
    pairs.push_back({t, s});
    correspondences.push_back({target_means[t].cast<double>(), as_matrix(target_covariances[t]),
                               source_means[s].cast<double>(), as_matrix(source_covariances[s])});
  }
  const Eigen::Isometry3d T = se3::exp((se3::Vector6d() << 0.1, -0.2, 0.3, 1, 2, -1).finished());
  const GicpBlock indexed(target_means, target_covariances, source_means, source_covariances, pairs,
                          T);
  const GicpBlock reference(correspondences, T);
  ASSERT_EQ(indexed.num_rows(), reference.num_rows());
  const Eigen::Isometry3d at = T * se3::exp(se3::Vector6d::Constant(0.01));
  Eigen::Matrix<double, 6, 6> H_indexed, H_reference;
  Eigen::Matrix<double, 6, 1> b_indexed, b_reference;
  EXPECT_EQ(indexed.accumulate_at(at, &H_indexed, &b_indexed),
            reference.accumulate_at(at, &H_reference, &b_reference));
  EXPECT_EQ(H_indexed, H_reference);
  EXPECT_EQ(b_indexed, b_reference);

  pairs[5][0] = 300;
  try {
    GicpBlock block(target_means, target_covariances, source_means, source_covariances, pairs, T);
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), ("GicpBlock: pair 5 names target point 300 of 300 and source point " +
                            std::to_string(pairs[5][1]) + " of 2500")
                               .c_str());
  }
  pairs[5][0] = 0;
  source_covariances[pairs[9][1]][3] = -1.0f;  // not positive definite
  source_means[pairs[40][1]].y() = std::nanf("");
  try {
    GicpBlock block(target_means, target_covariances, source_means, source_covariances, pairs, T);
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(),
                 "GicpBlock: correspondence 9: fused covariance is not positive definite");
  }
}

}  // namespace
}  // namespace carat
