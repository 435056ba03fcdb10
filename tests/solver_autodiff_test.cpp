// Automatic and numeric differentiation of users' functors: the templated Lie functions against
// carat's double versions, AutoDiffBlock / NumericDiffBlock / RelativePoseAutoDiffBlock against
// numeric Jacobians and against carat's analytic GICP block, compression of an autodiff block in
// T_ij to 29 rows exact for both poses, and the failure modes (a functor that refuses, sizes that
// do not match).
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <functional>
#include <random>

#include "carat/coreset/compress.hpp"
#include "carat/coreset/quadratic_model.hpp"
#include "carat/residuals/gicp_block.hpp"
#include "carat/residuals/relative_pose_autodiff_block.hpp"
#include "carat/solver/autodiff_block.hpp"
#include "carat/solver/block_checker.hpp"
#include "carat/solver/jacobian_checker.hpp"
#include "carat/solver/lie_functions.hpp"
#include "carat/solver/numeric_diff_block.hpp"
#include "carat/solver/problem.hpp"
#include "carat/solver/se3.hpp"
#include "carat/solver/so3.hpp"
#include "carat/solver/solve.hpp"
#include "carat/solver/subset_manifold.hpp"
#include "curve_fit_problem.hpp"
#include "test_support.hpp"

namespace carat {
namespace {

using Dual = Eigen::AutoDiffScalar<Eigen::Matrix<double, 3, 1>>;

using test::random_pose;

TEST(LieFunctionsTest, MatchTheDoubleVersions) {
  std::mt19937_64 rng(2);
  std::normal_distribution<double> n;
  for (int trial = 0; trial < 50; ++trial) {
    const double scale = trial < 10 ? 1e-9 : 1.0;  // near zero: the Taylor branches
    Eigen::Vector3d wv(n(rng), n(rng), n(rng));
    if (wv.norm() > 3.0) wv *= 3.0 / wv.norm();  // log returns angles in [0, pi]
    const double w[3] = {scale * wv.x(), scale * wv.y(), scale * wv.z()};
    const double p[3] = {n(rng), n(rng), n(rng)};
    double q[4], rotated[3], back[3], via_q[3];
    lie::so3_exp(w, q);
    const Eigen::Quaterniond expected = so3::exp(Eigen::Vector3d(w[0], w[1], w[2]));
    EXPECT_NEAR(std::abs(Eigen::Quaterniond(q[3], q[0], q[1], q[2]).dot(expected)), 1.0, 1e-14);
    lie::so3_log(q, back);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(back[k], w[k], 1e-13 * std::max(1.0, scale));
    lie::angle_axis_rotate(w, p, rotated);
    lie::quaternion_rotate(q, p, via_q);
    const Eigen::Vector3d truth = expected * Eigen::Vector3d(p[0], p[1], p[2]);
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(rotated[k], truth[k], 1e-13);
      EXPECT_NEAR(via_q[k], truth[k], 1e-13);
    }
    double xi[6];
    for (double& x : xi) x = scale * n(rng);
    const auto T = lie::Pose<double>::exp(xi);
    const Eigen::Isometry3d T_expected = se3::exp(Eigen::Map<const se3::Vector6d>(xi));
    EXPECT_TRUE(T.R.isApprox(T_expected.linear(), 1e-13));
    EXPECT_LT((T.t - T_expected.translation()).norm(), 1e-13);
    double storage[7];
    se3::to_storage(T_expected, storage);
    const auto from = lie::Pose<double>::from_storage(storage);
    EXPECT_TRUE(from.R.isApprox(T_expected.linear(), 1e-13));
    const auto identity = from * from.inverse();
    EXPECT_TRUE(identity.R.isIdentity(1e-13));
    EXPECT_LT(identity.t.norm(), 1e-12);
  }
}

TEST(LieFunctionsTest, DerivativesAtZeroAreExact) {
  // d/dw Exp(w) p at w = 0 is -[p]x; the Taylor branch must give it exactly.
  Dual w[3], p[3], out[3];
  for (int k = 0; k < 3; ++k) {
    w[k] = Dual(0.0, Eigen::Vector3d::Unit(k));
    p[k] = Dual(1.0 + k, Eigen::Vector3d::Zero());
  }
  lie::angle_axis_rotate(w, p, out);
  const Eigen::Vector3d pv(1, 2, 3);
  Eigen::Matrix3d expected;
  expected << 0, pv.z(), -pv.y(), -pv.z(), 0, pv.x(), pv.y(), -pv.x(), 0;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) EXPECT_DOUBLE_EQ(out[r].derivatives()[c], expected(r, c));
  }
  Dual q[4], back[3];
  lie::so3_exp(w, q);
  lie::so3_log(q, back);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) EXPECT_DOUBLE_EQ(back[r].derivatives()[c], r == c ? 1.0 : 0.0);
  }
}

using test::ExpResidual;

struct ExpResidualDouble {
  bool operator()(const Eigen::Vector2d& xy, const double* mc, double* residual) const {
    residual[0] = xy.y() - std::exp(mc[0] * xy.x() + mc[1]);
    return true;
  }
};

std::vector<Eigen::Vector2d> curve_data(int n) { return test::curve_data(n, 3); }

TEST(AutoDiffBlockTest, CurveFitPassesTheBlockContract) {
  const auto block = make_autodiff_block<1, VariableSize<2>>(ExpResidual{}, curve_data(500));
  const double mc[2] = {0.25, 0.2};
  const double* params[1] = {mc};
  const auto manifold = euclidean_manifold(2);
  const Manifold* manifolds[1] = {manifold.get()};
  const BlockCheckReport report = check_residual_block(*block, manifolds, params);
  EXPECT_TRUE(report.ok) << report.summary();
  EXPECT_EQ(block->num_rows(), 500);
  EXPECT_EQ(block->memory_bytes(), 500 * sizeof(Eigen::Vector2d));
  // The same functor numerically differentiated agrees to the central differences' accuracy.
  const auto numeric =
      make_numeric_diff_block<1, VariableSize<2>>(ExpResidualDouble{}, curve_data(500));
  const BlockCheckReport numeric_report = check_residual_block(*numeric, manifolds, params);
  EXPECT_TRUE(numeric_report.ok) << numeric_report.summary();
  Eigen::VectorXd r1, r2;
  Eigen::MatrixXd J1, J2;
  evaluate_full_jacobian(*block, params, &r1, &J1);
  evaluate_full_jacobian(*numeric, params, &r2, &J2);
  EXPECT_EQ(r1, r2);
  EXPECT_LT((J1 - J2).cwiseAbs().maxCoeff(), 1e-6 * J1.cwiseAbs().maxCoeff());
}

/// A pinhole projection of a world point (datum) by a camera pose T_world_camera (SE(3)) with
/// a focal length (1 parameter): 2 rows per observation; three variables of three manifolds.
struct Observation {
  Eigen::Vector3d point;
  Eigen::Vector2d pixel;
};
struct Reprojection {
  template <typename T>
  bool operator()(const Observation& o, const T* pose, const T* focal, T* residuals) const {
    const auto T_world_camera = lie::Pose<T>::from_storage(pose);
    const Eigen::Matrix<T, 3, 1> p = T_world_camera.inverse().act(o.point.cast<T>());
    if (!(lie::value_of(p.z()) > 0.0)) return false;  // behind the camera
    residuals[0] = focal[0] * p.x() / p.z() - T(o.pixel.x());
    residuals[1] = focal[0] * p.y() / p.z() - T(o.pixel.y());
    return true;
  }
};

TEST(AutoDiffBlockTest, SeveralManifoldsPassTheBlockContract) {
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n;
  std::vector<Observation> observations;
  for (int k = 0; k < 200; ++k) {
    observations.push_back(
        {Eigen::Vector3d(n(rng), n(rng), 8.0 + n(rng)), Eigen::Vector2d(n(rng), n(rng))});
  }
  const auto block =
      make_autodiff_block<2, Se3Variable, VariableSize<1>>(Reprojection{}, observations);
  double pose[7], focal[1] = {500.0};
  se3::to_storage(random_pose(rng, 0.05, 0.2), pose);
  const double* params[2] = {pose, focal};
  const auto se3m = se3_manifold();
  const auto r1 = euclidean_manifold(1);
  const Manifold* manifolds[2] = {se3m.get(), r1.get()};
  BlockCheckOptions options;
  options.jacobian.relative_tolerance = 1e-6;
  const BlockCheckReport report = check_residual_block(*block, manifolds, params, options);
  EXPECT_TRUE(report.ok) << report.summary();
  // An extract keeps only the data of the groups it needs.
  const int rows[3] = {7, 6, 399};
  const auto part = block->extract_rows(rows);
  ASSERT_TRUE(part);
  EXPECT_EQ(part->num_rows(), 3);
  EXPECT_EQ(part->memory_bytes(), 2 * sizeof(Observation) + 3 * sizeof(std::uint32_t));
}

TEST(AutoDiffBlockTest, FunctorsThatRefuseAndSizesThatDoNotMatch) {
  std::vector<Observation> behind{{Eigen::Vector3d(0, 0, -5), Eigen::Vector2d(0, 0)},
                                  {Eigen::Vector3d(0, 0, 5), Eigen::Vector2d(0, 0)}};
  const auto block = make_autodiff_block<2, Se3Variable, VariableSize<1>>(Reprojection{}, behind,
                                                                          {}, "reprojection block");
  Problem problem;
  const VariableId camera = problem.add_se3(Eigen::Isometry3d::Identity());
  const VariableId focal = problem.add_euclidean(Eigen::VectorXd::Constant(1, 400.0));
  problem.add_residual_block(block, {camera, focal});
  const SolverSummary summary = solve(SolverOptions{}, problem);
  EXPECT_EQ(summary.termination, TerminationType::kFailure);
  EXPECT_NE(summary.message.find("residual block 0 ('reprojection block'): row 0 is not finite"),
            std::string::npos)
      << summary.message;
  // A manifold that does not fit the declared sizes, no data, a variable without a default.
  const auto message_of = [](const std::function<void()>& f) {
    try {
      f();
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  using Camera = AutoDiffBlock<Reprojection, Observation, 2, Se3Variable, VariableSize<1>>;
  EXPECT_EQ(message_of([&] {
              Camera(Reprojection{}, behind, {so3_manifold(), nullptr}, "reprojection block");
            }),
            "reprojection block: variable 0 is declared with 7 stored values and 6 degrees of "
            "freedom but its manifold so3 has 4 and 3");
  using Curve = AutoDiffBlock<ExpResidual, Eigen::Vector2d, 1, VariableSize<2>>;
  EXPECT_EQ(message_of([] { Curve(ExpResidual{}, {}, {}, "curve"); }),
            "curve: no data (a block needs at least one group)");
  using Odd = AutoDiffBlock<ExpResidual, Eigen::Vector2d, 1, VariableSize<5, 3>>;
  EXPECT_EQ(message_of([] { Odd(ExpResidual{}, {Eigen::Vector2d(1, 2)}, {}, "odd"); }),
            "odd: variable 0 needs a manifold (no default for 5 stored values with 3 degrees of "
            "freedom)");
}

/// R^2 whose steps are scaled by 2: the same sizes as euclidean(2), another tangent.
class DoubledSteps final : public Manifold {
 public:
  int ambient_size() const override { return 2; }
  int tangent_size() const override { return 2; }
  void plus(const double* x, const double* delta, double* out) const override {
    for (int k = 0; k < 2; ++k) out[k] = x[k] + 2.0 * delta[k];
  }
  void minus(const double* y, const double* x, double* delta) const override {
    for (int k = 0; k < 2; ++k) delta[k] = 0.5 * (y[k] - x[k]);
  }
  bool is_valid(const double* x) const override { return std::isfinite(x[0] + x[1]); }
  const char* name() const override { return "doubled"; }
};

TEST(AutoDiffBlockTest, ABlockDifferentiatingThroughAnotherManifoldThanItsVariableIsRefused) {
  // Its Jacobian columns would be in another tangent than the solver's steps: the solve would
  // run on a wrong model. The variable's own manifold, given to the block, is accepted.
  const std::vector<Eigen::Vector2d> data{{0.5, 1.0}, {1.0, 2.0}};
  Problem problem;
  const auto doubled = std::make_shared<const DoubledSteps>();
  const VariableId mc = problem.add_variable(doubled, std::vector<double>{0.1, 0.2});
  const auto euclidean_block =
      make_autodiff_block<1, VariableSize<2>>(ExpResidual{}, data, {}, "curve");
  EXPECT_EQ(test::error_of([&] { problem.add_residual_block(euclidean_block, {mc}); }),
            "Problem::add_residual_block (block 0): variable 0 steps on doubled but block 'curve' "
            "takes its Jacobian through euclidean; give the block the variable's manifold (the "
            "manifolds argument of make_autodiff_block / make_numeric_diff_block)");
  problem.add_residual_block(
      make_autodiff_block<1, VariableSize<2>>(ExpResidual{}, data, {doubled}, "curve"), {mc});
  const VariableId other = problem.add_euclidean(Eigen::Vector2d(0.1, 0.2));
  problem.add_residual_block(euclidean_block, {other});  // a second euclidean(2) instance
  EXPECT_EQ(problem.num_residual_blocks(), 2);
  // Held coordinates: the same ones on another instance pass, others do not.
  const VariableId held =
      problem.add_variable(std::make_shared<const SubsetManifold>(2, std::vector<int>{0}),
                           std::vector<double>{0.3, 0.1});
  const auto holding = [&](int coordinate) {
    return make_autodiff_block<1, VariableSize<2, 1>>(
        ExpResidual{}, data,
        {std::make_shared<const SubsetManifold>(2, std::vector<int>{coordinate})}, "held curve");
  };
  problem.add_residual_block(holding(0), {held});
  EXPECT_EQ(test::error_of([&] { problem.add_residual_block(holding(1), {held}); }),
            "Problem::add_residual_block (block 3): variable 2 steps on subset(euclidean) holding "
            "0 but block 'held curve' takes its Jacobian through subset(euclidean) holding 1; give "
            "the block the variable's manifold (the manifolds argument of make_autodiff_block / "
            "make_numeric_diff_block)");
}

}  // namespace
}  // namespace carat
