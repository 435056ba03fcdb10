// Marginal covariances against the dense inverse of the Gauss-Newton Hessian: pose graphs (with
// and without a robust loss, pairs on and off the factor's pattern), the Schur complement's
// kept and eliminated variables, gauge freedoms (the error naming the free variables, the
// pseudo-inverse), and bad input.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/residuals/bal_problem.hpp"
#include "carat/residuals/pose_graph.hpp"
#include "carat/sim/bal_scene.hpp"
#include "carat/sim/pose_graph.hpp"
#include "carat/solver/autodiff_block.hpp"
#include "carat/solver/covariance.hpp"
#include "carat/solver/loss_function.hpp"
#include "carat/solver/problem.hpp"
#include "covariance_test_support.hpp"
#include "solver_test_blocks.hpp"
#include "test_support.hpp"

namespace carat {
namespace {

using test::dense_hessian;
using test::dense_inverse;
using test::dense_pseudo_inverse;
using test::relative_error;

/// Every block and pair of `covariance` against the dense `reference` (over free variables,
/// offsets as dense_hessian() gives them), to `tolerance` relative per block.
void expect_blocks_match(const Problem& problem, const Covariance& covariance,
                         const Eigen::MatrixXd& reference, const std::vector<int>& offsets,
                         double tolerance) {
  for (int a = 0; a < problem.num_variables(); ++a) {
    const int oa = offsets[static_cast<std::size_t>(a)];
    if (oa < 0) continue;
    const int da = problem.manifold(VariableId{a}).tangent_size();
    for (int b = 0; b < problem.num_variables(); ++b) {
      const int ob = offsets[static_cast<std::size_t>(b)];
      if (ob < 0) continue;
      const int db = problem.manifold(VariableId{b}).tangent_size();
      const Eigen::MatrixXd expected = reference.block(oa, ob, da, db);
      const Eigen::MatrixXd got = covariance.block(VariableId{a}, VariableId{b});
      // Off-diagonal blocks may be small: relative to the two variables' own blocks.
      const double scale = std::sqrt(reference.block(oa, oa, da, da).norm() *
                                     reference.block(ob, ob, db, db).norm());
      ASSERT_LE((got - expected).norm(), tolerance * scale) << "variables " << a << ", " << b;
    }
  }
}

/// The synthetic city-block pose graph, small: 24 poses, loop closures every 3 on lap 2.
PoseGraphProblem small_pose_graph(std::shared_ptr<const LossFunction> loss = nullptr) {
  SyntheticPoseGraphOptions options;
  options.poses_per_lap = 12;
  options.laps = 2;
  options.loop_closure_stride = 3;
  options.seed = 4;
  PoseGraphProblemOptions problem_options;
  problem_options.loss = std::move(loss);
  return build_pose_graph_problem(make_synthetic_pose_graph(options).graph, problem_options);
}

TEST(CovarianceTest, PoseGraphEqualsTheDenseInverse) {
  PoseGraphProblem built = small_pose_graph();
  std::vector<int> offsets;
  const Eigen::MatrixXd H = dense_hessian(built.problem, &offsets);
  const Eigen::MatrixXd reference = dense_inverse(H);
  const Covariance covariance(built.problem);
  EXPECT_EQ(covariance.size(), H.rows());
  EXPECT_EQ(covariance.gauge_dimension(), 0);
  expect_blocks_match(built.problem, covariance, reference, offsets, 1e-10);
  // Poses joined by an edge are on the factor's pattern; the first and the middle of lap 1
  // (joined by no edge and far apart in the elimination) take solves.
  EXPECT_TRUE(covariance.on_pattern(built.vertex_variables[1], built.vertex_variables[2]));
  EXPECT_TRUE(covariance.on_pattern(built.vertex_variables[5], built.vertex_variables[5]));
  int off_pattern = 0;
  for (VariableId a : built.vertex_variables) {
    for (VariableId b : built.vertex_variables) {
      if (!built.problem.is_constant(a) && !built.problem.is_constant(b)) {
        off_pattern += covariance.on_pattern(a, b) ? 0 : 1;
      }
    }
  }
  EXPECT_GT(off_pattern, 0);
}

TEST(CovarianceTest, RobustLossAppliedAsTheSolverAppliesIt) {
  // At the drifting start many edges are far out on the Cauchy loss: rho'' terms in H.
  PoseGraphProblem built = small_pose_graph(std::make_shared<CauchyLoss>(0.5));
  std::vector<int> offsets;
  const Eigen::MatrixXd reference = dense_inverse(dense_hessian(built.problem, &offsets));
  const Covariance covariance(built.problem);
  expect_blocks_match(built.problem, covariance, reference, offsets, 1e-10);
}

TEST(CovarianceTest, ConstantVariablesHaveNone) {
  PoseGraphProblem built = small_pose_graph();
  const Covariance covariance(built.problem);
  EXPECT_EQ(test::error_of([&] { covariance.block(built.vertex_variables[0]); }),
            "covariance: variable 0 is constant: it has no covariance");
  EXPECT_EQ(test::error_of(
                [&] { covariance.block(built.vertex_variables[3], built.vertex_variables[0]); }),
            "covariance: variable 0 is constant: it has no covariance");
  EXPECT_EQ(test::error_of([&] { covariance.block(VariableId{99}); }),
            "covariance: variable 99 is not in the problem");
  EXPECT_FALSE(covariance.on_pattern(built.vertex_variables[0], built.vertex_variables[1]));
}

TEST(CovarianceTest, GaugeFreedomIsAnErrorNamingTheFreeVariables) {
  PoseGraphProblem built = small_pose_graph();
  built.problem.set_constant(built.vertex_variables[0], false);
  EXPECT_EQ(test::error_of([&] { const Covariance covariance(built.problem); }),
            "covariance: H is singular: 6 free directions (a gauge freedom or an unobservable "
            "direction) move variables 0, 1, 2, 3, 4, 5, 6, 7, ... (24 in all); hold a variable "
            "constant, add a prior, or ask for the pseudo-inverse gauge");
}

TEST(CovarianceTest, GaugeFreedomUnderThePseudoInverse) {
  PoseGraphProblem built = small_pose_graph();
  built.problem.set_constant(built.vertex_variables[0], false);
  std::vector<int> offsets;
  const Eigen::MatrixXd H = dense_hessian(built.problem, &offsets);
  const Eigen::MatrixXd reference = dense_pseudo_inverse(H, 6);
  Covariance::Options options;
  options.gauge = CovarianceGauge::kPseudoInverse;
  const Covariance covariance(built.problem, options);
  EXPECT_EQ(covariance.gauge_dimension(), 6);
  expect_blocks_match(built.problem, covariance, reference, offsets, 1e-10);
}

/// A camera T_world_camera (SE(3)) measuring a point (Euclidean 3, world) in its own frame:
/// r = R^T (p - t) - z.
struct PointInCamera {
  template <typename T>
  bool operator()(const Eigen::Vector3d& z, const T* pose, const T* point, T* r) const {
    // Rotate d = p - t by the inverse of the unit quaternion [qx, qy, qz, qw].
    const T d[3] = {point[0] - pose[4], point[1] - pose[5], point[2] - pose[6]};
    const T q[3] = {-pose[0], -pose[1], -pose[2]};
    const T w = pose[3];
    const T c[3] = {q[1] * d[2] - q[2] * d[1], q[2] * d[0] - q[0] * d[2],
                    q[0] * d[1] - q[1] * d[0]};  // q x d
    const T cc[3] = {q[1] * c[2] - q[2] * c[1], q[2] * c[0] - q[0] * c[2],
                     q[0] * c[1] - q[1] * c[0]};  // q x (q x d)
    for (int k = 0; k < 3; ++k) r[k] = d[k] + T(2.0) * (w * c[k] + cc[k]) - T(z[k]);
    return true;
  }
};

/// Cameras on a ring, each point seen by 3 of them; points marked eliminable.
struct Landmarks {
  Problem problem;
  std::vector<VariableId> cameras, points;
};

Landmarks make_landmarks(int num_cameras, int num_points) {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 0.05);
  Landmarks out;
  std::vector<Eigen::Isometry3d> poses;
  for (int c = 0; c < num_cameras; ++c) {
    poses.push_back(test::random_pose(rng, 0.5, 4.0));
    out.cameras.push_back(out.problem.add_se3(poses.back()));
  }
  for (int p = 0; p < num_points; ++p) {
    const Eigen::Vector3d truth = 3.0 * Eigen::Vector3d::Random();
    out.points.push_back(out.problem.add_euclidean(truth));
    out.problem.set_eliminable(out.points.back());
    for (int v = 0; v < 3; ++v) {
      const auto c = static_cast<std::size_t>((p + v) % num_cameras);
      const Eigen::Vector3d z =
          poses[c].inverse() * truth + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
      out.problem.add_residual_block(make_autodiff_block<3, Se3Variable, VariableSize<3>>(
                                         PointInCamera{}, std::vector<Eigen::Vector3d>{z}),
                                     {out.cameras[c], out.points.back()});
    }
  }
  return out;
}

TEST(CovarianceTest, SchurComplementKeptAndEliminatedVariables) {
  Landmarks landmarks = make_landmarks(6, 30);
  landmarks.problem.set_constant(landmarks.cameras[0]);
  std::vector<int> offsets;
  const Eigen::MatrixXd reference = dense_inverse(dense_hessian(landmarks.problem, &offsets));
  Covariance::Options options;
  options.linear_solver = LinearSolver::kSchur;
  const Covariance schur(landmarks.problem, options);
  EXPECT_NE(schur.description().find("schur complement"), std::string::npos);
  // Cameras from S's sparse inverse, points by back-substitution, camera-point and point-point
  // pairs by solves.
  EXPECT_TRUE(schur.on_pattern(landmarks.cameras[1], landmarks.cameras[2]));
  EXPECT_TRUE(schur.on_pattern(landmarks.points[4], landmarks.points[4]));
  EXPECT_FALSE(schur.on_pattern(landmarks.points[4], landmarks.cameras[2]));
  expect_blocks_match(landmarks.problem, schur, reference, offsets, 1e-10);
  options.linear_solver = LinearSolver::kCholesky;
  const Covariance whole(landmarks.problem, options);
  EXPECT_NE(whole.description().find("cholmod supernodal"), std::string::npos);
  expect_blocks_match(landmarks.problem, whole, reference, offsets, 1e-10);
}

TEST(CovarianceTest, BundleAdjustmentGaugeIsNamed) {
  BalSimulationOptions scene_options;
  scene_options.cameras = 5;
  scene_options.points = 40;
  scene_options.observations_per_point = 3;
  Problem problem;
  add_bal_problem(simulate_bal(scene_options).truth, &problem);
  // Similarity: rotation, translation and scale of the whole scene, through every variable.
  EXPECT_EQ(test::error_of([&] { const Covariance covariance(problem); }),
            "covariance: H is singular: 7 free directions (a gauge freedom or an unobservable "
            "direction) move variables 0, 1, 2, 3, 4, 5, 6, 7, ... (45 in all); hold a variable "
            "constant, add a prior, or ask for the pseudo-inverse gauge");
  Covariance::Options options;
  options.gauge = CovarianceGauge::kPseudoInverse;
  EXPECT_EQ(Covariance(problem, options).gauge_dimension(), 7);
}

TEST(CovarianceTest, EliminatedVariableUndeterminedByItsOwnBlocksIsAnError) {
  BalSimulationOptions scene_options;
  scene_options.cameras = 4;
  scene_options.points = 20;
  BalProblem bal = simulate_bal(scene_options).truth;
  // One more point, seen by camera 0 alone: two rows for three coordinates.
  bal.points.push_back(bal.points[0]);
  BalObservation seen = bal.observations[0];
  seen.point = static_cast<int>(bal.points.size()) - 1;
  bal.observations.push_back(seen);
  Problem problem;
  const BalVariables variables = add_bal_problem(bal, &problem);
  problem.set_constant(variables.cameras[0]);
  problem.set_constant(variables.cameras[1]);
  Covariance::Options options;
  options.gauge = CovarianceGauge::kPseudoInverse;
  EXPECT_EQ(test::error_of([&] { const Covariance covariance(problem, options); }),
            "covariance: variable 24 is eliminated but not determined by its own blocks alone (a "
            "singular V, e.g. a point seen along one ray): no covariance (remove, or solve the "
            "whole system: LinearSolver::kCholesky)");
}

TEST(CovarianceTest, EliminatedVariablesGaugeUnderThePseudoInverse) {
  Landmarks landmarks = make_landmarks(6, 30);  // nothing constant: a rigid motion is free
  std::vector<int> offsets;
  const Eigen::MatrixXd H = dense_hessian(landmarks.problem, &offsets);
  Covariance::Options options;
  options.gauge = CovarianceGauge::kPseudoInverse;
  // The Schur complement: the cameras' perturbation orthogonal to the free directions, so their
  // covariance is S^+ (the free directions found and removed on S alone), the points following
  // by back-substitution.
  const Covariance schur(landmarks.problem, options);
  EXPECT_EQ(schur.gauge_dimension(), 6);
  std::vector<char> kept(static_cast<std::size_t>(H.rows()), 0);
  for (VariableId camera : landmarks.cameras) {
    for (int k = 0; k < 6; ++k) {
      kept[static_cast<std::size_t>(offsets[static_cast<std::size_t>(camera.index)] + k)] = 1;
    }
  }
  expect_blocks_match(landmarks.problem, schur, test::dense_kept_gauge(H, 6, kept), offsets, 1e-10);
  // The whole system: every variable's perturbation orthogonal to them, H^+.
  options.linear_solver = LinearSolver::kCholesky;
  const Covariance whole(landmarks.problem, options);
  EXPECT_EQ(whole.gauge_dimension(), 6);
  expect_blocks_match(landmarks.problem, whole, dense_pseudo_inverse(H, 6), offsets, 1e-10);
}

TEST(CovarianceTest, UntouchedVariableIsAnError) {
  Problem problem;
  const VariableId x = problem.add_euclidean(Eigen::Vector2d(1.0, 2.0));
  problem.add_euclidean(Eigen::Vector3d::Zero());
  problem.add_residual_block(
      std::make_shared<test::LinearBlock>(std::vector<Eigen::MatrixXd>{Eigen::Matrix2d::Identity()},
                                          Eigen::Vector2d(0.5, 0.5)),
      {x});
  EXPECT_EQ(test::error_of([&] { const Covariance covariance(problem); }),
            "covariance: variable 1 is free but touched by no residual block: nothing constrains "
            "it (hold constant or remove)");
}

TEST(CovarianceTest, UnobservableDirectionIsAnErrorOrDropped) {
  // x (2) and y (1) seen only through x0 + y and x1: the direction x0 = -y is free.
  Problem problem;
  const VariableId x = problem.add_euclidean(Eigen::Vector2d(1.0, 2.0));
  const VariableId y = problem.add_euclidean(Eigen::VectorXd::Constant(1, 0.5));
  const VariableId z = problem.add_euclidean(Eigen::VectorXd::Constant(1, 0.0));
  Eigen::MatrixXd A_x(3, 2), A_y(3, 1), A_z(1, 1);
  A_x << 1.0, 0.0, 0.0, 2.0, 0.0, 0.0;
  A_y << 1.0, 0.0, 0.0;
  A_z << 3.0;
  problem.add_residual_block(std::make_shared<test::LinearBlock>(
                                 std::vector<Eigen::MatrixXd>{A_x, A_y}, Eigen::Vector3d::Ones()),
                             {x, y});
  problem.add_residual_block(std::make_shared<test::LinearBlock>(std::vector<Eigen::MatrixXd>{A_z},
                                                                 Eigen::VectorXd::Ones(1)),
                             {z});
  EXPECT_EQ(test::error_of([&] { const Covariance covariance(problem); }),
            "covariance: H is singular: 1 free direction (a gauge freedom or an unobservable "
            "direction) move variables 0, 1; hold a variable constant, add a prior, or ask for "
            "the pseudo-inverse gauge");
  std::vector<int> offsets;
  const Eigen::MatrixXd reference = dense_pseudo_inverse(dense_hessian(problem, &offsets), 1);
  Covariance::Options options;
  options.gauge = CovarianceGauge::kPseudoInverse;
  const Covariance covariance(problem, options);
  EXPECT_EQ(covariance.gauge_dimension(), 1);
  expect_blocks_match(problem, covariance, reference, offsets, 1e-12);
  // z is untouched by the free direction: its variance is 1 / 9.
  EXPECT_NEAR(covariance.block(z)(0, 0), 1.0 / 9.0, 1e-15);
}

TEST(CovarianceTest, BadOptions) {
  PoseGraphProblem built = small_pose_graph();
  Covariance::Options options;
  options.max_variance_inflation = 0.5;
  EXPECT_EQ(test::error_of([&] { const Covariance covariance(built.problem, options); }),
            "covariance: max_variance_inflation must be finite and > 1");
}

}  // namespace
}  // namespace carat
