// The synthetic BAL scene: exact counts, determinism, every observed point in front of its
// camera, zero cost at the noise-free truth, exact outlier count, and a small scene solved from
// its perturbed start down to the noise floor.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cstring>
#include <vector>

#include "carat/residuals/bal_problem.hpp"
#include "carat/sim/bal_scene.hpp"
#include "carat/solver/solve.hpp"
#include "carat/solver/solver_options.hpp"
#include "test_support.hpp"

namespace carat {
namespace {

/// Whether two problems hold the same bits.
bool identical(const BalProblem& a, const BalProblem& b) {
  if (a.cameras.size() != b.cameras.size() || a.points.size() != b.points.size() ||
      a.observations.size() != b.observations.size()) {
    return false;
  }
  for (std::size_t i = 0; i < a.cameras.size(); ++i) {
    if (std::memcmp(a.cameras[i].data(), b.cameras[i].data(), 9 * sizeof(double)) != 0)
      return false;
  }
  for (std::size_t i = 0; i < a.points.size(); ++i) {
    if (std::memcmp(a.points[i].data(), b.points[i].data(), 3 * sizeof(double)) != 0) return false;
  }
  for (std::size_t k = 0; k < a.observations.size(); ++k) {
    const BalObservation &p = a.observations[k], &q = b.observations[k];
    if (p.camera != q.camera || p.point != q.point || std::memcmp(&p.x, &q.x, sizeof(double)) ||
        std::memcmp(&p.y, &q.y, sizeof(double))) {
      return false;
    }
  }
  return true;
}

struct SizeCase {
  BalLayout layout;
  int cameras, points, per_point;
};

class BalSceneSizeTest : public ::testing::TestWithParam<SizeCase> {};

TEST_P(BalSceneSizeTest, HasExactlyTheCountsAskedForAndEveryPointInFront) {
  BalSimulationOptions options;
  options.layout = GetParam().layout;
  options.cameras = GetParam().cameras;
  options.points = GetParam().points;
  options.observations_per_point = GetParam().per_point;
  options.outlier_fraction = 0.1;
  const BalScene scene = simulate_bal(options);
  for (const BalProblem* p : {&scene.truth, &scene.problem}) {
    EXPECT_EQ(p->cameras.size(), static_cast<std::size_t>(options.cameras));
    EXPECT_EQ(p->points.size(), static_cast<std::size_t>(options.points));
    EXPECT_EQ(p->observations.size(),
              static_cast<std::size_t>(options.points) * options.observations_per_point);
    EXPECT_NO_THROW(check_bal_problem(*p));  // every camera observes, every point is observed
  }
  EXPECT_EQ(count_points_behind_cameras(scene.truth), 0u);
  EXPECT_EQ(count_points_behind_cameras(scene.problem), 0u);
  // Each point is observed by distinct cameras, exactly observations_per_point of them.
  for (int j = 0; j < options.points; ++j) {
    std::vector<int> cameras;
    for (int i = 0; i < options.observations_per_point; ++i) {
      const BalObservation& o =
          scene.truth
              .observations[static_cast<std::size_t>(j * options.observations_per_point + i)];
      ASSERT_EQ(o.point, j);
      cameras.push_back(o.camera);
    }
    std::sort(cameras.begin(), cameras.end());
    ASSERT_EQ(std::adjacent_find(cameras.begin(), cameras.end()), cameras.end()) << "point " << j;
  }
  const auto outliers =
      static_cast<std::size_t>(std::count(scene.outlier.begin(), scene.outlier.end(), char{1}));
  EXPECT_EQ(outliers, static_cast<std::size_t>(std::llround(
                          0.1 * static_cast<double>(scene.truth.observations.size()))));
  EXPECT_LE(bal_cost(scene.truth), 1e-20);
}

INSTANTIATE_TEST_SUITE_P(Layouts, BalSceneSizeTest,
                         ::testing::Values(SizeCase{BalLayout::kRing, 16, 22106, 4},
                                           SizeCase{BalLayout::kStreet, 100, 20000, 8},
                                           SizeCase{BalLayout::kRandom, 500, 2000, 3},
                                           SizeCase{BalLayout::kRing, 600, 600, 2},
                                           SizeCase{BalLayout::kStreet, 5, 5, 5}),
                         [](const ::testing::TestParamInfo<SizeCase>& param_info) {
                           return std::string(to_string(param_info.param.layout)) +
                                  std::to_string(param_info.param.cameras) + "x" +
                                  std::to_string(param_info.param.points);
                         });

TEST(BalSceneTest, SameSeedSameSceneOtherSeedOtherScene) {
  for (BalLayout layout : {BalLayout::kRing, BalLayout::kStreet, BalLayout::kRandom}) {
    BalSimulationOptions options;
    options.layout = layout;
    options.cameras = 12;
    options.points = 300;
    options.outlier_fraction = 0.05;
    options.seed = 42;
    const BalScene a = simulate_bal(options), b = simulate_bal(options);
    EXPECT_TRUE(identical(a.truth, b.truth));
    EXPECT_TRUE(identical(a.problem, b.problem));
    EXPECT_EQ(a.outlier, b.outlier);
    options.seed = 43;
    EXPECT_FALSE(identical(a.problem, simulate_bal(options).problem));
  }
}

TEST(BalSceneTest, NoiseFreeTruthHasZeroCostThroughTheProblem) {
  BalSimulationOptions options;
  options.pixel_noise_sigma = 0.0;
  options.cameras = 10;
  options.points = 400;
  const BalScene scene = simulate_bal(options);
  EXPECT_LE(bal_cost(scene.truth), 1e-20);
  Problem problem;
  add_bal_problem(scene.truth, &problem);
  EXPECT_LE(problem.evaluate_cost(), 1e-20);
  // Without noise the observations are the truth's; the start alone costs something.
  for (std::size_t k = 0; k < scene.truth.observations.size(); ++k) {
    EXPECT_EQ(scene.problem.observations[k].x, scene.truth.observations[k].x);
  }
  EXPECT_GT(bal_cost(scene.problem), 100.0);
}

TEST(BalSceneTest, SolvingASmallSceneReachesTheNoiseFloor) {
  BalSimulationOptions options;
  options.cameras = 8;
  options.points = 500;
  options.observations_per_point = 4;
  options.pixel_noise_sigma = 1.0;
  options.seed = 7;
  const BalScene scene = simulate_bal(options);
  // The truth with the noisy observations: the noise floor a solution must reach (or beat).
  BalProblem noisy_truth = scene.truth;
  noisy_truth.observations = scene.problem.observations;
  const double floor = bal_cost(noisy_truth);
  const std::size_t rows = 2 * scene.problem.observations.size();
  EXPECT_NEAR(floor, 0.5 * static_cast<double>(rows), 0.1 * static_cast<double>(rows));

  Problem problem;
  const BalVariables variables = add_bal_problem(scene.problem, &problem);
  const double initial = problem.evaluate_cost();
  EXPECT_GT(initial, 20.0 * floor);
  const SolverSummary summary = solve(SolverOptions{}, problem);
  ASSERT_TRUE(summary.is_solution_usable()) << summary.brief_report();
  // The Gauss-Newton phase on the Schur complement: its radius leaves the gauge freedom
  // (nothing is held constant) damped just enough for every reduced system to factorize.
  ASSERT_NE(summary.linear_solver.find("schur complement"), std::string::npos);
  EXPECT_EQ(summary.iterations.front().trust_region_radius,
            SolverOptions{}.gauss_newton_phase_radius);
  EXPECT_EQ(summary.num_linear_solver_failures, 0) << summary.full_report();
  // Least squares fits part of the noise: the optimum lies below the floor, by about
  // 1/2 sigma^2 (parameters - 7 gauge freedoms) in expectation.
  EXPECT_LE(summary.final_cost, floor);
  const double parameters = 9.0 * options.cameras + 3.0 * options.points - 7.0;
  EXPECT_GE(summary.final_cost, 0.8 * (floor - 0.5 * parameters));
  // Kept in the XML report (--gtest_output=xml): start, noise floor, optimum, iterations.
  RecordProperty("initial_cost", std::to_string(initial));
  RecordProperty("noise_floor", std::to_string(floor));
  RecordProperty("final_cost", std::to_string(summary.final_cost));
  RecordProperty("iterations", std::to_string(summary.num_iterations));
  BalProblem solved = scene.problem;
  update_bal_problem(problem, variables, &solved);
  EXPECT_NEAR(bal_cost(solved), summary.final_cost, 1e-9 * summary.final_cost);
  EXPECT_EQ(count_points_behind_cameras(solved), 0u);
}

/// The scene moved by `shift` (scene units): every camera centre and point.
BalProblem shifted(BalProblem bal, const Eigen::Vector3d& shift) {
  for (BalCamera& camera : bal.cameras) {
    const Eigen::Vector3d w = camera.head<3>();
    const Eigen::Matrix3d R = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
    camera.segment<3>(3) -= R * shift;  // t = -R c, and c moves by shift
  }
  for (Eigen::Vector3d& point : bal.points) point += shift;
  return bal;
}

/// The cost after each iteration of solve() with its defaults.
std::vector<double> iteration_costs(const BalProblem& bal, BalCameraTangent tangent) {
  Problem problem;
  add_bal_problem(bal, &problem, nullptr, tangent);
  const SolverSummary summary = solve(SolverOptions{}, problem);
  std::vector<double> costs;
  for (const IterationSummary& it : summary.iterations) costs.push_back(it.cost);
  return costs;
}

TEST(BalSceneTest, CameraStepsAboutTheirCentreDoNotDependOnWhereTheWorldOriginIs) {
  BalSimulationOptions options;
  options.cameras = 8;
  options.points = 300;
  options.seed = 7;
  const BalProblem bal = simulate_bal(options).problem;
  const BalProblem far = shifted(bal, {1000.0, 300.0, 0.0});
  // About the centre: the same iterations 1 km from the origin, to the shift's rounding.
  const std::vector<double> near_centre = iteration_costs(bal, BalCameraTangent::kAboutCentre);
  const std::vector<double> far_centre = iteration_costs(far, BalCameraTangent::kAboutCentre);
  ASSERT_EQ(near_centre.size(), far_centre.size());
  ASSERT_GE(near_centre.size(), 3u);
  for (std::size_t k = 0; k < near_centre.size(); ++k) {
    EXPECT_NEAR(far_centre[k], near_centre[k], 1e-6 * near_centre[k]) << "iteration " << k;
  }
  // Steps added to [w, t]: a rotation step swings the camera about the origin 1 km away, and the
  // first step lands far above the optimum.
  const std::vector<double> far_parameters = iteration_costs(far, BalCameraTangent::kParameters);
  EXPECT_GT(far_parameters[1], 10.0 * far_centre[1]);
  EXPECT_NEAR(far_parameters.back(), far_centre.back(), 1e-6 * far_centre.back());
}

TEST(BalSceneTest, LayoutNamesAndOptionErrors) {
  for (BalLayout layout : {BalLayout::kRing, BalLayout::kStreet, BalLayout::kRandom}) {
    EXPECT_EQ(parse_bal_layout(to_string(layout)), layout);
  }
  EXPECT_EQ(test::error_of([] { (void)parse_bal_layout("circle"); }),
            "unknown BAL layout 'circle' (valid: ring, street, random)");
  BalSimulationOptions options;
  options.points = 10;
  EXPECT_EQ(test::error_of([&] { (void)simulate_bal(options); }),
            "simulate_bal: points must be >= cameras (16) so that every camera observes one, got "
            "10");
  options = {};
  options.observations_per_point = 17;
  EXPECT_EQ(test::error_of([&] { (void)simulate_bal(options); }),
            "simulate_bal: observations_per_point must be in [2, cameras = 16], got 17");
  options = {};
  options.outlier_fraction = 1.5;
  EXPECT_EQ(test::error_of([&] { (void)simulate_bal(options); }),
            "simulate_bal: outlier_fraction must be in [0, 1], got 1.5");
  options = {};
  options.pixel_noise_sigma = -1.0;
  EXPECT_EQ(test::error_of([&] { (void)simulate_bal(options); }),
            "simulate_bal: pixel_noise_sigma must be finite and >= 0, got -1");
}

TEST(BalSceneTest, ObserverCountsTheLayoutCannotPlaceAreRefusedUpFront) {
  EXPECT_EQ(max_observations_per_point(BalLayout::kStreet, 500), 57);
  EXPECT_EQ(max_observations_per_point(BalLayout::kStreet, 20), 20);
  EXPECT_EQ(max_observations_per_point(BalLayout::kRing, 500), 500);
  BalSimulationOptions options;
  options.layout = BalLayout::kStreet;
  options.cameras = 300;
  options.points = 300;
  options.observations_per_point = 58;
  EXPECT_EQ(test::error_of([&] { (void)simulate_bal(options); }),
            "simulate_bal: observations_per_point must be at most 57 for the street layout (no "
            "facade point is in front of more consecutive cameras), got 58");
  // The bound is the geometry's: at it, every point is placed.
  options.observations_per_point = 57;
  const BalScene scene = simulate_bal(options);
  EXPECT_EQ(scene.problem.observations.size(), 300u * 57u);
  EXPECT_EQ(count_points_behind_cameras(scene.truth), 0u);
}

/// The linear solver kAuto picks for `scene` (its summary's description), solving no step.
std::string auto_linear_solver(const BalProblem& bal, double max_bytes = 0.0) {
  Problem problem;
  add_bal_problem(bal, &problem);
  SolverOptions options;
  options.max_iterations = 0;
  options.max_linear_system_bytes = max_bytes;
  const SolverSummary summary = solve(options, problem);
  return summary.termination == TerminationType::kFailure ? "FAILURE: " + summary.message
                                                          : summary.linear_solver;
}

TEST(BalSceneTest, AutoLinearSolverPicksTheSystemThatFits) {
  // Few cameras per point: the Schur complement, as always.
  BalSimulationOptions sparse;
  sparse.cameras = 16;
  sparse.points = 1000;
  EXPECT_EQ(auto_linear_solver(simulate_bal(sparse).problem).rfind("schur complement", 0), 0u);
  // Every point seen by a third of 150 cameras: the reduced camera system is dense (1350 x 1350,
  // about 22 MB with its factor) while the whole system, cameras eliminated first, keeps the
  // points' 450 x 450 block: the whole system is factorized.
  BalSimulationOptions dense;
  dense.layout = BalLayout::kRandom;
  dense.cameras = 150;
  dense.points = 150;
  dense.observations_per_point = 50;
  const BalProblem bal = simulate_bal(dense).problem;
  EXPECT_EQ(auto_linear_solver(bal).rfind("cholmod supernodal", 0), 0u);
  // Neither fits 1 MB: refused with both estimates.
  const std::string refused = auto_linear_solver(bal, 1e6);
  EXPECT_EQ(refused.rfind("FAILURE: linear solver auto: neither system fits: the Schur complement "
                          "needs about ",
                          0),
            0u)
      << refused;
  EXPECT_NE(refused.find(" and sparse Cholesky of the whole system about "), std::string::npos);
  EXPECT_NE(refused.find("976.6 KiB may be used"), std::string::npos) << refused;
}

}  // namespace
}  // namespace carat
