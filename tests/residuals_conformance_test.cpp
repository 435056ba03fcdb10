// Every residual block carat ships passes the block contract (check_residual_block): pose-graph
// blocks, the registration blocks and their extracts, lossless rows, coresets and random
// samples, and the blocks built from functors. A plugin that ignores `rows` is caught.
#include <gtest/gtest.h>

#include <functional>
#include <random>

#include "carat/coreset/compress.hpp"
#include "carat/residuals/bal_camera_manifold.hpp"
#include "carat/residuals/gicp_block.hpp"
#include "carat/residuals/lossless_block.hpp"
#include "carat/residuals/point_to_plane_block.hpp"
#include "carat/residuals/point_to_point_block.hpp"
#include "carat/residuals/pose_prior_block.hpp"
#include "carat/residuals/relative_pose_autodiff_block.hpp"
#include "carat/residuals/relative_pose_block.hpp"
#include "carat/residuals/relative_pose_se2_block.hpp"
#include "carat/residuals/snavely_block.hpp"
#include "carat/solver/autodiff_block.hpp"
#include "carat/solver/block_checker.hpp"
#include "carat/solver/lie_functions.hpp"
#include "carat/solver/numeric_diff_block.hpp"
#include "carat/solver/se2.hpp"
#include "carat/solver/se3.hpp"

namespace carat {
namespace {

/// A block with values for its variables, ready to check.
struct Case {
  std::shared_ptr<const ResidualBlock> block;
  std::vector<std::shared_ptr<const Manifold>> manifolds;
  std::vector<std::vector<double>> values;
};

using Factory = std::function<Case()>;

Eigen::Isometry3d random_pose(std::mt19937_64& rng, double rotation = 0.5, double shift = 2.0) {
  std::normal_distribution<double> n;
  se3::Vector6d xi;
  for (int k = 0; k < 3; ++k) xi[k] = rotation * n(rng);
  for (int k = 3; k < 6; ++k) xi[k] = shift * n(rng);
  return se3::exp(xi);
}

std::vector<double> storage(const Eigen::Isometry3d& T) {
  std::vector<double> x(7);
  se3::to_storage(T, x.data());
  return x;
}

se3::Matrix6d information(std::mt19937_64& rng) {
  std::normal_distribution<double> n;
  se3::Matrix6d A;
  for (int i = 0; i < 36; ++i) A.data()[i] = n(rng);
  return A * A.transpose() + se3::Matrix6d::Identity();
}

/// Two poses and random GICP correspondences between their frames.
struct PosePair {
  Eigen::Isometry3d T_world_i, T_world_j;
  std::vector<GicpCorrespondence> correspondences;
  Eigen::Isometry3d T_ij() const { return T_world_i.inverse() * T_world_j; }
  Case with(std::shared_ptr<const ResidualBlock> block) const {
    return {std::move(block),
            {se3_manifold(), se3_manifold()},
            {storage(T_world_i), storage(T_world_j)}};
  }
};

PosePair pose_pair(int n = 300) {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> normal;
  PosePair out{random_pose(rng), random_pose(rng), {}};
  for (int k = 0; k < n; ++k) {
    Eigen::Matrix3d A, B;
    for (int i = 0; i < 9; ++i) {
      A.data()[i] = normal(rng);
      B.data()[i] = normal(rng);
    }
    out.correspondences.push_back({Eigen::Vector3d(normal(rng), normal(rng), normal(rng)) * 5,
                                   A * A.transpose() + 0.01 * Eigen::Matrix3d::Identity(),
                                   Eigen::Vector3d(normal(rng), normal(rng), normal(rng)) * 5,
                                   B * B.transpose() + 0.01 * Eigen::Matrix3d::Identity()});
  }
  return out;
}

std::shared_ptr<GicpBlock> gicp_block(const PosePair& p) {
  return std::make_shared<GicpBlock>(p.correspondences, p.T_ij());
}

std::vector<Eigen::Vector3d> targets(const PosePair& p) {
  std::vector<Eigen::Vector3d> out;
  for (const auto& c : p.correspondences) out.push_back(c.mean_target);
  return out;
}
std::vector<Eigen::Vector3d> sources(const PosePair& p) {
  std::vector<Eigen::Vector3d> out;
  for (const auto& c : p.correspondences) out.push_back(c.mean_source);
  return out;
}

struct ExpResidual {
  template <typename T>
  bool operator()(const Eigen::Vector2d& xy, const T* mc, T* r) const {
    using std::exp;
    r[0] = T(xy.y()) - exp(mc[0] * xy.x() + mc[1]);
    return true;
  }
};
struct ExpResidualDouble {
  bool operator()(const Eigen::Vector2d& xy, const double* mc, double* r) const {
    r[0] = xy.y() - std::exp(mc[0] * xy.x() + mc[1]);
    return true;
  }
};
struct PointToPointFunctor {
  template <typename T>
  bool operator()(const std::pair<Eigen::Vector3d, Eigen::Vector3d>& m, const lie::Pose<T>& T_ij,
                  T* r) const {
    const Eigen::Matrix<T, 3, 1> e = m.first.cast<T>() - T_ij.act(m.second.cast<T>());
    for (int k = 0; k < 3; ++k) r[k] = e[k];
    return true;
  }
};

std::vector<Eigen::Vector2d> curve(int n) {
  std::vector<Eigen::Vector2d> data;
  for (int k = 0; k < n; ++k)
    data.emplace_back(0.01 * k, std::exp(0.3 * 0.01 * k) + 0.01 * (k % 7));
  return data;
}

const std::vector<std::pair<std::string, Factory>>& cases() {
  static const std::vector<std::pair<std::string, Factory>> all = {
      {"RelativePoseBlock",
       [] {
         std::mt19937_64 rng(1);
         const auto Ti = random_pose(rng), Tj = random_pose(rng);
         return Case{
             std::make_shared<RelativePoseBlock>(random_pose(rng, 0.1, 0.1), information(rng)),
             {se3_manifold(), se3_manifold()},
             {storage(Ti), storage(Tj)}};
       }},
      {"RelativePoseSE2Block",
       [] {
         std::mt19937_64 rng(12);
         std::normal_distribution<double> n;
         std::vector<double> xi(3), xj(3);
         se2::to_storage(se2::make(2.0 * n(rng), 2.0 * n(rng), n(rng)), xi.data());
         se2::to_storage(se2::make(2.0 * n(rng), 2.0 * n(rng), n(rng)), xj.data());
         Eigen::Matrix3d A;
         for (int i = 0; i < 9; ++i) A.data()[i] = n(rng);
         return Case{std::make_shared<RelativePoseSE2Block>(
                         se2::make(1.0, 0.5, 0.3), A * A.transpose() + Eigen::Matrix3d::Identity()),
                     {se2_manifold(), se2_manifold()},
                     {xi, xj}};
       }},
      {"PosePriorBlock",
       [] {
         std::mt19937_64 rng(2);
         return Case{std::make_shared<PosePriorBlock>(random_pose(rng), information(rng)),
                     {se3_manifold()},
                     {storage(random_pose(rng))}};
       }},
      {"GicpBlock",
       [] {
         const PosePair p = pose_pair();
         return p.with(gicp_block(p));
       }},
      {"GicpBlockSingleRowExtract",
       [] {
         const PosePair p = pose_pair();
         const int rows[] = {5, 4, 300, 899, 17};
         return p.with(std::shared_ptr<const ResidualBlock>(gicp_block(p)->extract_rows(rows)));
       }},
      {"GicpBlockWeightedExtract",
       [] {
         const PosePair p = pose_pair();
         const int rows[] = {5, 4, 300, 899, 17};
         const double weights[] = {2.0, 0.5, 1.0, 7.0, 3.0};
         return p.with(std::shared_ptr<const ResidualBlock>(
             gicp_block(p)->extract_weighted_rows(rows, weights)));
       }},
      {"PointToPlaneBlock",
       [] {
         const PosePair p = pose_pair();
         std::vector<Eigen::Vector3d> normals;
         for (const auto& c : p.correspondences) normals.push_back(c.mean_source.normalized());
         return p.with(std::make_shared<PointToPlaneBlock>(targets(p), normals, sources(p)));
       }},
      {"PointToPointBlock",
       [] {
         const PosePair p = pose_pair();
         return p.with(std::make_shared<PointToPointBlock>(targets(p), sources(p)));
       }},
      {"LosslessRegistrationBlock",
       [] {
         const PosePair p = pose_pair();
         return p.with(make_lossless_block(*gicp_block(p), p.T_ij()));
       }},
      {"CompressedGicpBlock",
       [] {
         const PosePair p = pose_pair();
         Case c = p.with(nullptr);
         const double* values[2] = {c.values[0].data(), c.values[1].data()};
         c.block = compress(gicp_block(p), values);
         return c;
       }},
      {"CompressedPointToPointBlockUnfolded",
       [] {
         const PosePair p = pose_pair();
         Case c = p.with(nullptr);
         const double* values[2] = {c.values[0].data(), c.values[1].data()};
         c.block = compress(std::make_shared<PointToPointBlock>(targets(p), sources(p)), values);
         return c;
       }},
      {"RandomSample",
       [] {
         const PosePair p = pose_pair();
         RandomSamplingOptions options;
         options.group_size = 3;
         options.target_rows = 30;
         return p.with(compress_random(gicp_block(p), options));
       }},
      {"AutoDiffBlock",
       [] {
         return Case{make_autodiff_block<1, VariableSize<2>>(ExpResidual{}, curve(400)),
                     {euclidean_manifold(2)},
                     {{0.25, 0.2}}};
       }},
      {"AutoDiffBlockExtract",
       [] {
         const auto block = make_autodiff_block<1, VariableSize<2>>(ExpResidual{}, curve(400));
         const int rows[] = {3, 399, 3, 200};
         return Case{std::shared_ptr<const ResidualBlock>(block->extract_rows(rows)),
                     {euclidean_manifold(2)},
                     {{0.25, 0.2}}};
       }},
      {"NumericDiffBlock",
       [] {
         return Case{make_numeric_diff_block<1, VariableSize<2>>(ExpResidualDouble{}, curve(400)),
                     {euclidean_manifold(2)},
                     {{0.25, 0.2}}};
       }},
      {"SnavelyReprojectionBlock",
       [] {
         // A BAL camera [w, t, f, k1, k2] 10 m from a point in front of it.
         return Case{std::make_shared<SnavelyReprojectionBlock>(31.5, -12.25),
                     {euclidean_manifold(9), euclidean_manifold(3)},
                     {{0.2, -0.4, 0.3, 0.5, -0.3, -10.0, 480.0, -0.05, 0.004}, {0.8, 1.2, -0.6}}};
       }},
      {"SnavelyReprojectionBlockAboutCentre",
       [] {
         // The same camera stepped about its centre (bal_camera_manifold()).
         return Case{std::make_shared<SnavelyReprojectionBlock>(31.5, -12.25,
                                                                BalCameraTangent::kAboutCentre),
                     {bal_camera_manifold(), euclidean_manifold(3)},
                     {{0.2, -0.4, 0.3, 0.5, -0.3, -10.0, 480.0, -0.05, 0.004}, {0.8, 1.2, -0.6}}};
       }},
      {"RelativePoseAutoDiffBlock",
       [] {
         const PosePair p = pose_pair();
         std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> matches;
         for (const auto& c : p.correspondences) matches.emplace_back(c.mean_target, c.mean_source);
         return p.with(make_relative_pose_block<3>(PointToPointFunctor{}, matches));
       }},
  };
  return all;
}

class BlockContractTest : public ::testing::TestWithParam<std::size_t> {};

TEST_P(BlockContractTest, PassesTheConformanceCheck) {
  const Case c = cases()[GetParam()].second();
  ASSERT_TRUE(c.block);
  std::vector<const Manifold*> manifolds;
  for (const auto& m : c.manifolds) manifolds.push_back(m.get());
  std::vector<const double*> params;
  for (const auto& v : c.values) params.push_back(v.data());
  BlockCheckOptions options;
  options.jacobian.relative_tolerance = 1e-6;
  const BlockCheckReport report = check_residual_block(*c.block, manifolds, params, options);
  EXPECT_TRUE(report.ok) << report.summary();
}

INSTANTIATE_TEST_SUITE_P(EveryShippedBlock, BlockContractTest,
                         ::testing::Range<std::size_t>(0, cases().size()),
                         [](const ::testing::TestParamInfo<std::size_t>& param_info) {
                           return cases()[param_info.param].first;
                         });

/// A plugin that writes all its rows whatever `rows` asks for, and one whose tangent_dims()
/// returns a span over a temporary.
class CarelessBlock final : public ResidualBlock {
 public:
  explicit CarelessBlock(bool temporary_dims) : temporary_dims_(temporary_dims) {}
  int num_rows() const override { return 300; }
  std::span<const int> tangent_dims() const override {
    if (!temporary_dims_) return dims_;
    fresh_ = std::make_unique<std::array<int, 1>>(std::array<int, 1>{1});  // a new one each call
    return *fresh_;
  }
  void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* r,
                     double* J) const override {
    const std::size_t count = temporary_dims_ ? rows.size() : 300;  // ignores `rows`
    for (std::size_t k = 0; k < count; ++k) {
      r[k] = params[0][0] - static_cast<double>(k);
      if (J) J[k] = 1.0;
    }
  }
  std::size_t memory_bytes() const override { return 0; }

 private:
  bool temporary_dims_;
  std::array<int, 1> dims_{1};
  mutable std::unique_ptr<std::array<int, 1>> fresh_;
};

TEST(BlockContractTest, CatchesPluginsThatBreakTheContract) {
  const auto manifold = euclidean_manifold(1);
  const Manifold* manifolds[1] = {manifold.get()};
  const double x[1] = {2.0};
  const double* params[1] = {x};
  const BlockCheckReport rows = check_residual_block(CarelessBlock(false), manifolds, params);
  EXPECT_FALSE(rows.ok);
  EXPECT_NE(rows.summary().find("evaluate_rows() asked for row 0 wrote 299 more residuals and 299 "
                                "more Jacobian entries (it must write only the rows in `rows`)"),
            std::string::npos)
      << rows.summary();
  const BlockCheckReport dims = check_residual_block(CarelessBlock(true), manifolds, params);
  EXPECT_FALSE(dims.ok);
  EXPECT_NE(dims.summary().find("tangent_dims() returns a different span on each call"),
            std::string::npos)
      << dims.summary();
}

/// A block whose evaluate_rows() writes one row more than asked: the default accumulate() and
/// squared_norm() see the write in their guard row and say so.
class OneRowTooManyBlock final : public ResidualBlock {
 public:
  int num_rows() const override { return 1000; }
  std::span<const int> tangent_dims() const override { return dims_; }
  void evaluate_rows(ParameterPointers, std::span<const int> rows, double* r,
                     double* J) const override {
    for (std::size_t k = 0; k <= rows.size() && k < 129; ++k) {
      r[k] = 1.0;
      if (J) J[k] = 1.0;
    }
  }
  std::size_t memory_bytes() const override { return 0; }

 private:
  std::array<int, 1> dims_{1};
};

TEST(BlockContractTest, TheDefaultPathsCatchAWritePastTheRowsAsked) {
  const double x[1] = {0.0};
  const double* params[1] = {x};
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(1, 1);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(1);
  EXPECT_THROW(OneRowTooManyBlock().accumulate(params, H, b), Error);
  EXPECT_THROW(OneRowTooManyBlock().squared_norm(params), Error);
}

}  // namespace
}  // namespace carat
