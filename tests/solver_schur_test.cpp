// The Schur complement: the reduced system's step equals the whole system's, the solver reaches
// the same optimum on bundle-adjustment problems through either path, the automatic choice,
// bit-identical results for any number of threads, and the errors of a group that cannot be
// eliminated.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "../solver/src/block_evaluator.hpp"
#include "../solver/src/schur_system.hpp"
#include "../solver/src/sparse_system.hpp"
#include "carat/base/error.hpp"
#include "carat/solver/autodiff_block.hpp"
#include "carat/solver/lie_functions.hpp"
#include "carat/solver/loss_function.hpp"
#include "carat/solver/problem.hpp"
#include "carat/solver/solve.hpp"
#include "carat/solver/solver_options.hpp"
#include "solver_test_blocks.hpp"

namespace carat {
namespace {

/// Pixel reprojection of a point through a camera [angle-axis, t, (f), (k1, k2)]: 6, 7 or 9
/// numbers (focal length 1 and no distortion when absent), minus-sign pinhole.
template <int kCamera>
struct Reprojection {
  template <typename T>
  bool operator()(const Eigen::Vector2d& observed, const T* camera, const T* point,
                  T* residual) const {
    T p[3];
    lie::angle_axis_rotate(camera, point, p);
    for (int k = 0; k < 3; ++k) p[k] += camera[3 + k];
    const T x = -p[0] / p[2];
    const T y = -p[1] / p[2];
    T scale = T(1.0);
    if constexpr (kCamera >= 7) scale = camera[6];
    if constexpr (kCamera == 9) {
      const T r2 = x * x + y * y;
      scale = scale * (T(1.0) + camera[7] * r2 + camera[8] * r2 * r2);
    }
    residual[0] = scale * x - observed.x();
    residual[1] = scale * y - observed.y();
    return true;
  }
};

/// A small bundle-adjustment problem: cameras on a ring looking at points near the centre,
/// every point seen by `views` cameras, noisy observations, perturbed starting values.
template <int kCamera>
struct BundleProblem {
  Problem problem;
  std::vector<VariableId> cameras, points;
};

template <int kCamera>
BundleProblem<kCamera> make_bundle(int num_cameras, int num_points, int views, unsigned seed,
                                   bool mark_points,
                                   std::shared_ptr<const LossFunction> loss = nullptr) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  BundleProblem<kCamera> out;
  std::vector<Eigen::Matrix<double, kCamera, 1>> truth_cameras;
  for (int c = 0; c < num_cameras; ++c) {
    // Camera c on a circle of radius 10, looking at the origin: its optical axis is -z.
    const double angle = 2.0 * M_PI * c / num_cameras;
    const Eigen::Vector3d centre(10.0 * std::cos(angle), 10.0 * std::sin(angle),
                                 0.5 * uniform(rng));
    const Eigen::Vector3d back = centre.normalized();  // camera +z points away from the origin
    const Eigen::Vector3d right = Eigen::Vector3d::UnitZ().cross(back).normalized();
    Eigen::Matrix3d R_world_camera;
    R_world_camera << right, back.cross(right), back;
    const Eigen::Matrix3d R_camera_world = R_world_camera.transpose();
    const Eigen::AngleAxisd aa(R_camera_world);
    Eigen::Matrix<double, kCamera, 1> camera;
    camera.template head<3>() = aa.angle() * aa.axis();
    camera.template segment<3>(3) = -R_camera_world * centre;
    if constexpr (kCamera >= 7) camera[6] = 500.0;
    if constexpr (kCamera == 9) camera.template tail<2>() << 1e-2, -1e-3;
    truth_cameras.push_back(camera);
  }
  std::vector<Eigen::Vector3d> truth_points;
  for (int p = 0; p < num_points; ++p)
    truth_points.emplace_back(2.0 * uniform(rng), 2.0 * uniform(rng), 2.0 * uniform(rng));
  for (const auto& camera : truth_cameras) {
    Eigen::Matrix<double, kCamera, 1> start = camera;
    for (int k = 0; k < 6; ++k) start[k] += 0.01 * noise(rng);
    out.cameras.push_back(out.problem.add_euclidean(start));
  }
  for (const auto& point : truth_points) {
    const Eigen::Vector3d start =
        point + 0.05 * Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    out.points.push_back(out.problem.add_euclidean(start));
    if (mark_points) out.problem.set_eliminable(out.points.back());
  }
  const double pixel = kCamera >= 7 ? 1.0 : 1.0 / 500.0;
  for (int p = 0; p < num_points; ++p) {
    const int first = static_cast<int>(rng() % static_cast<unsigned>(num_cameras));
    for (int v = 0; v < views; ++v) {
      const int c = (first + v * 3) % num_cameras;
      Eigen::Vector2d r;
      Reprojection<kCamera>{}(Eigen::Vector2d::Zero(),
                              truth_cameras[static_cast<std::size_t>(c)].data(),
                              truth_points[static_cast<std::size_t>(p)].data(), r.data());
      const Eigen::Vector2d observed = r + pixel * Eigen::Vector2d(noise(rng), noise(rng));
      auto block = make_autodiff_block<2, VariableSize<kCamera>, VariableSize<3>>(
          Reprojection<kCamera>{}, std::vector<Eigen::Vector2d>{observed});
      out.problem.add_residual_block(
          block,
          {out.cameras[static_cast<std::size_t>(c)], out.points[static_cast<std::size_t>(p)]},
          loss);
    }
  }
  return out;
}

/// The blocks of `ba` (camera 0 held) linearized at its values, and its points marked for
/// elimination.
template <int kCamera>
void linearize_bundle(BundleProblem<kCamera>& ba, internal::BlockLinearizations* blocks,
                      std::vector<char>* eliminate) {
  ba.problem.set_constant(ba.cameras[0]);
  internal::BlockEvaluator evaluator(ba.problem);
  std::vector<double> values(ba.problem.all_values().begin(), ba.problem.all_values().end());
  evaluator.bind(0, values.data());
  evaluator.allocate(blocks);
  std::string error;
  ASSERT_TRUE(evaluator.linearize(0, blocks, &error)) << error;
  eliminate->assign(static_cast<std::size_t>(ba.problem.num_variables()), 0);
  for (VariableId p : ba.points) (*eliminate)[static_cast<std::size_t>(p.index)] = 1;
}

/// The step of both systems for one damping, in variable order.
template <int kCamera>
void expect_same_step(int num_cameras, int num_points) {
  BundleProblem<kCamera> ba = make_bundle<kCamera>(num_cameras, num_points, 4, 7, true);
  internal::BlockLinearizations blocks;
  std::vector<char> eliminate;
  ASSERT_NO_FATAL_FAILURE(linearize_bundle(ba, &blocks, &eliminate));
  internal::SchurSystem schur(ba.problem, eliminate, Ordering::kAuto);
  internal::SparseSystem full(ba.problem, Ordering::kAuto);
  ASSERT_EQ(schur.size(), full.size());
  EXPECT_EQ(schur.num_eliminated(), num_points);
  EXPECT_EQ(schur.reduced_size(), (num_cameras - 1) * kCamera);

  Eigen::VectorXd g_schur, g_full;
  schur.assemble(blocks, &g_schur);
  full.assemble(blocks, &g_full);
  // Both systems in variable order.
  // Between a system's layout and the variables' order (free variables only).
  const auto reorder = [&](const internal::LinearSystem& system, const Eigen::VectorXd& x,
                           bool to_variables) {
    Eigen::VectorXd out(x.size());
    Eigen::Index offset = 0;
    for (int v = 0; v < ba.problem.num_variables(); ++v) {
      const int o = system.variable_offset()[static_cast<std::size_t>(v)];
      if (o < 0) continue;
      const int d = ba.problem.manifold(VariableId{v}).tangent_size();
      if (to_variables) {
        out.segment(offset, d) = x.segment(o, d);
      } else {
        out.segment(o, d) = x.segment(offset, d);
      }
      offset += d;
    }
    return out;
  };
  const auto to_variable_order = [&](const internal::LinearSystem& system,
                                     const Eigen::VectorXd& x) { return reorder(system, x, true); };
  const auto from_variable_order = [&](const internal::LinearSystem& system,
                                       const Eigen::VectorXd& x) {
    return reorder(system, x, false);
  };
  const Eigen::VectorXd g = to_variable_order(full, g_full);
  EXPECT_LE((to_variable_order(schur, g_schur) - g).norm(), 1e-13 * g.norm());
  const Eigen::VectorXd diagonal = to_variable_order(full, full.diagonal());
  EXPECT_LE((to_variable_order(schur, schur.diagonal()) - diagonal).norm(),
            1e-13 * diagonal.norm());

  // H x agrees, and so does the damped step for a small and a large damping.
  const Eigen::VectorXd x = Eigen::VectorXd::LinSpaced(g.size(), -1.0, 1.0);
  Eigen::VectorXd y_schur, y_full;
  schur.multiply(from_variable_order(schur, x), &y_schur);
  full.multiply(from_variable_order(full, x), &y_full);
  const Eigen::VectorXd y = to_variable_order(full, y_full);
  EXPECT_LE((to_variable_order(schur, y_schur) - y).norm(), 1e-12 * y.norm());
  for (const double lambda : {1e-6, 1e-1}) {
    const Eigen::VectorXd damping = lambda * diagonal;
    ASSERT_TRUE(schur.factorize(from_variable_order(schur, damping)));
    ASSERT_TRUE(full.factorize(from_variable_order(full, damping)));
    Eigen::VectorXd step_schur, step_full;
    schur.solve(from_variable_order(schur, -g), &step_schur);
    full.solve(from_variable_order(full, -g), &step_full);
    const Eigen::VectorXd expected = to_variable_order(full, step_full);
    EXPECT_LE((to_variable_order(schur, step_schur) - expected).norm(), 1e-8 * expected.norm())
        << "damping " << lambda;
  }
}

/// The step for the right-hand side factorize() reduced on its way (the solver's -gradient)
/// and for one it did not expect: the same bits, for each kernel.
template <int kCamera>
void expect_same_bits_reduced_before_or_after(int num_cameras, int num_points) {
  BundleProblem<kCamera> ba = make_bundle<kCamera>(num_cameras, num_points, 4, 11, true);
  internal::BlockLinearizations blocks;
  std::vector<char> eliminate;
  ASSERT_NO_FATAL_FAILURE(linearize_bundle(ba, &blocks, &eliminate));
  internal::SchurSystem schur(ba.problem, eliminate, Ordering::kAuto);
  Eigen::VectorXd gradient;
  schur.assemble(blocks, &gradient);
  const Eigen::VectorXd rhs = -gradient;
  const Eigen::VectorXd damping = 1e-3 * schur.diagonal();
  Eigen::VectorXd reduced_on_the_way, reduced_after, other;
  ASSERT_TRUE(schur.factorize(damping));  // assemble() expected -gradient
  schur.solve(rhs, &reduced_on_the_way);
  schur.expect_rhs(Eigen::VectorXd());
  ASSERT_TRUE(schur.factorize(damping));
  schur.solve(rhs, &reduced_after);
  ASSERT_EQ(reduced_on_the_way.size(), reduced_after.size());
  for (Eigen::Index k = 0; k < rhs.size(); ++k)
    ASSERT_EQ(reduced_on_the_way[k], reduced_after[k]) << "entry " << k;
  // An expected right-hand side does not stand in for another one.
  schur.expect_rhs(rhs);
  ASSERT_TRUE(schur.factorize(damping));
  const Eigen::VectorXd half = 0.5 * rhs;
  schur.solve(half, &other);
  EXPECT_LE((other - 0.5 * reduced_after).norm(), 1e-12 * reduced_after.norm());
}

TEST(SchurSystemTest, ReducingTheRightHandSideWhileFormingTheSystemGivesTheSameBits) {
  expect_same_bits_reduced_before_or_after<9>(40, 300);
  expect_same_bits_reduced_before_or_after<6>(12, 200);
  expect_same_bits_reduced_before_or_after<7>(8, 120);
}

TEST(SchurSystemTest, StepEqualsWholeSystemStepWithNineParameterCameras) {
  expect_same_step<9>(8, 120);
}
TEST(SchurSystemTest, StepEqualsWholeSystemStepWithSixParameterCameras) {
  expect_same_step<6>(8, 120);
}
TEST(SchurSystemTest, StepEqualsWholeSystemStepWithOtherSizes) { expect_same_step<7>(8, 120); }

/// The ordering named in a system's description ("... AMD ordering ..."): AMD, METIS or NESDIS.
std::string ordering_in(const std::string& description) {
  for (const char* name : {"AMD", "METIS", "NESDIS"}) {
    if (description.find(std::string(name) + " ordering") != std::string::npos) return name;
  }
  return "none";
}

TEST(SchurSystemTest, AutoOrderingIsTheSameRuleOnBothPaths) {
  // Ordering::kAuto keeps AMD where its factor has little fill (under kNestedDissectionFill
  // times the matrix's nonzeros) and otherwise the cheapest of AMD, METIS and NESDIS, on the
  // whole system's variable graph and on the reduced system alike; an explicit choice is kept.
  // The reduced system of a ring of cameras fills little: AMD, with AMD's flops (where
  // NESDIS ties AMD, as here, CHOLMOD's own choice among the three was NESDIS).
  BundleProblem<9> ba = make_bundle<9>(20, 100, 3, 3, true);
  std::vector<char> eliminate(static_cast<std::size_t>(ba.problem.num_variables()), 0);
  for (VariableId p : ba.points) eliminate[static_cast<std::size_t>(p.index)] = 1;
  const internal::SchurSystem ring_auto(ba.problem, eliminate, Ordering::kAuto);
  const internal::SchurSystem ring_amd(ba.problem, eliminate, Ordering::kAmd);
  EXPECT_EQ(ordering_in(ring_auto.description()), "AMD");
  EXPECT_EQ(ring_auto.factor_flops(), ring_amd.factor_flops());
  EXPECT_EQ(ordering_in(ring_amd.description()), "AMD");
  EXPECT_EQ(
      ordering_in(internal::SchurSystem(ba.problem, eliminate, Ordering::kMetis).description()),
      "METIS");

  // Variables (2-D) on a side^3 grid, each joined to its neighbours along x, y and z; with
  // `eliminable_links`, each join goes through a 1-D variable of its own that the Schur
  // complement eliminates (marked in *mask), so that the reduced system has the grid's pattern.
  const auto grid_problem = [](int side, bool eliminable_links, std::vector<char>* mask) {
    Problem grid;
    std::vector<VariableId> ids;
    for (int k = 0; k < side * side * side; ++k) {
      ids.push_back(grid.add_euclidean(Eigen::Vector2d(k, 1)));
    }
    const auto join = [&](int a, int b) {
      const VariableId va = ids[static_cast<std::size_t>(a)];
      const VariableId vb = ids[static_cast<std::size_t>(b)];
      if (!eliminable_links) {
        grid.add_residual_block(std::make_shared<test::LinearBlock>(
                                    std::vector<Eigen::MatrixXd>{Eigen::Matrix2d::Identity(),
                                                                 -Eigen::Matrix2d::Identity()},
                                    Eigen::Vector2d(1.0, 0.0)),
                                {va, vb});
        return;
      }
      const VariableId link = grid.add_euclidean(Eigen::VectorXd::Constant(1, 0.5));
      for (VariableId end : {va, vb}) {
        grid.add_residual_block(
            std::make_shared<test::LinearBlock>(
                std::vector<Eigen::MatrixXd>{Eigen::Matrix2d::Identity(), Eigen::Vector2d(1, -1)},
                Eigen::Vector2d(1.0, 0.0)),
            {end, link});
      }
    };
    for (int k = 0; k < side * side * side; ++k) {
      if (k % side + 1 < side) join(k, k + 1);
      if (k / side % side + 1 < side) join(k, k + side);
      if (k / (side * side) + 1 < side) join(k, k + side * side);
    }
    if (mask) {
      mask->assign(static_cast<std::size_t>(grid.num_variables()), 1);
      for (VariableId v : ids) (*mask)[static_cast<std::size_t>(v.index)] = 0;
    }
    return grid;
  };
  // A 3-D grid fills much: the cheapest of the three, a nested dissection.
  const Problem grid = grid_problem(6, false, nullptr);
  const internal::SparseSystem grid_auto(grid, Ordering::kAuto);
  const internal::SparseSystem grid_amd(grid, Ordering::kAmd);
  const internal::SparseSystem grid_metis(grid, Ordering::kMetis);
  EXPECT_EQ(ordering_in(grid_auto.description()), "NESDIS");
  EXPECT_LT(grid_auto.factor_flops(), grid_amd.factor_flops());
  EXPECT_LT(grid_auto.factor_flops(), grid_metis.factor_flops());
  EXPECT_EQ(ordering_in(grid_amd.description()), "AMD");
  EXPECT_EQ(ordering_in(grid_metis.description()), "METIS");
  // The same grid as a reduced system: the same rule.
  std::vector<char> links;
  const Problem linked = grid_problem(6, true, &links);
  const internal::SchurSystem linked_auto(linked, links, Ordering::kAuto);
  EXPECT_NE(ordering_in(linked_auto.description()), "AMD");
  EXPECT_LT(linked_auto.factor_flops(),
            internal::SchurSystem(linked, links, Ordering::kAmd).factor_flops());
}

TEST(SchurSystemTest, UnobservedPointIsNotPositiveDefiniteWithoutDamping) {
  BundleProblem<6> ba = make_bundle<6>(6, 20, 3, 3, true);
  ba.points.push_back(ba.problem.add_euclidean(Eigen::Vector3d(0.0, 0.0, 0.0)));
  std::vector<char> eliminate(static_cast<std::size_t>(ba.problem.num_variables()), 0);
  for (VariableId p : ba.points) eliminate[static_cast<std::size_t>(p.index)] = 1;
  internal::SchurSystem schur(ba.problem, eliminate, Ordering::kAuto);
  internal::BlockEvaluator evaluator(ba.problem);
  std::vector<double> values(ba.problem.all_values().begin(), ba.problem.all_values().end());
  evaluator.bind(0, values.data());
  internal::BlockLinearizations blocks;
  evaluator.allocate(&blocks);
  std::string error;
  ASSERT_TRUE(evaluator.linearize(0, &blocks, &error)) << error;
  Eigen::VectorXd gradient;
  schur.assemble(blocks, &gradient);
  EXPECT_FALSE(schur.factorize(Eigen::VectorXd::Zero(schur.size())));
  EXPECT_TRUE(schur.factorize(Eigen::VectorXd::Constant(schur.size(), 1.0)));
}

SolverOptions tight_options(LinearSolver linear_solver) {
  SolverOptions options;
  options.linear_solver = linear_solver;
  options.function_tolerance = 1e-12;
  options.gradient_tolerance = 1e-12;
  options.parameter_tolerance = 1e-12;
  options.max_iterations = 100;
  return options;
}

TEST(SchurSolveTest, ReachesTheWholeSystemOptimum) {
  for (const bool fix_gauge : {true, false}) {
    BundleProblem<9> schur = make_bundle<9>(10, 300, 4, 11, true);
    BundleProblem<9> full = make_bundle<9>(10, 300, 4, 11, false);
    if (fix_gauge) {
      schur.problem.set_constant(schur.cameras[0]);
      full.problem.set_constant(full.cameras[0]);
    }
    const SolverSummary a = solve(tight_options(LinearSolver::kSchur), schur.problem);
    const SolverSummary b = solve(tight_options(LinearSolver::kCholesky), full.problem);
    ASSERT_TRUE(a.is_solution_usable()) << a.message;
    ASSERT_TRUE(b.is_solution_usable()) << b.message;
    EXPECT_NE(a.linear_solver.find("schur complement of 300 eliminated"), std::string::npos)
        << a.linear_solver;
    EXPECT_EQ(b.linear_solver.find("schur"), std::string::npos) << b.linear_solver;
    // Unit pixel noise: at the optimum 1/2 sum r^2 is about (rows - parameters) / 2.
    EXPECT_GT(a.initial_cost, 10.0 * a.final_cost);
    EXPECT_LT(a.final_cost, 0.5 * static_cast<double>(a.num_residual_rows));
    EXPECT_NEAR(a.final_cost, b.final_cost, 1e-9 * b.final_cost) << "gauge fixed: " << fix_gauge;
    EXPECT_TRUE(std::isfinite(a.final_cost));
    EXPECT_GT(a.time.schur_s, 0.0);
    EXPECT_EQ(b.time.schur_s, 0.0);
  }
}

/// A 3-D observation of a point in a camera's frame (a depth camera): R(w) p + t - observed.
struct CameraFramePoint {
  template <typename T>
  bool operator()(const Eigen::Vector3d& observed, const T* camera, const T* point,
                  T* residual) const {
    T p[3];
    lie::angle_axis_rotate(camera, point, p);
    for (int k = 0; k < 3; ++k) residual[k] = p[k] + camera[3 + k] - observed[k];
    return true;
  }
};

/// The difference of a point's positions in two cameras' frames: one block over two cameras and
/// the point.
struct TwoCameraFramePoint {
  template <typename T>
  bool operator()(const Eigen::Vector3d& observed, const T* a, const T* b, const T* point,
                  T* residual) const {
    T in_a[3], in_b[3];
    const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
    CameraFramePoint{}(zero, a, point, in_a);
    CameraFramePoint{}(zero, b, point, in_b);
    for (int k = 0; k < 3; ++k) residual[k] = in_a[k] - in_b[k] - observed[k];
    return true;
  }
};

/// Three-row blocks (each an edge's only contribution, scattered from its Jacobian rows) over
/// kCamera-parameter cameras (6: pose only): the Schur path reaches the whole system's optimum over
/// several linearizations (each writes W afresh). With `two_camera_blocks`, every fifth point is
/// also seen by a block over two cameras and itself (no longer the fused layout, found only
/// after many blocks).
template <int kCamera>
void expect_three_row_blocks_reach_the_whole_system_optimum(bool two_camera_blocks = false) {
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 1.0);
  Problem problems[2];
  for (int which = 0; which < 2; ++which) {
    rng.seed(5);
    Problem& problem = problems[which];
    std::vector<VariableId> cameras, points;
    std::vector<Eigen::Matrix<double, kCamera, 1>> truth;
    for (int c = 0; c < 8; ++c) {
      Eigen::Matrix<double, kCamera, 1> camera = Eigen::Matrix<double, kCamera, 1>::Zero();
      camera.template head<3>() << 0.1 * c, -0.05 * c, 0.02 * c;
      camera.template segment<3>(3) << 0.5 * c, 0.2, 5.0;
      truth.push_back(camera);
      Eigen::Matrix<double, kCamera, 1> start = camera;
      for (int k = 0; k < 6; ++k) start[k] += 0.02 * noise(rng);
      cameras.push_back(problem.add_euclidean(start));
    }
    problem.set_constant(cameras[0]);
    for (int p = 0; p < 150; ++p) {
      const Eigen::Vector3d point(noise(rng), noise(rng), noise(rng));
      points.push_back(problem.add_euclidean(point + 0.1 * Eigen::Vector3d::Random()));
      if (which == 0) problem.set_eliminable(points.back());
      for (int v = 0; v < 3; ++v) {
        const int c = (p + 3 * v) % 8;
        Eigen::Vector3d r;
        CameraFramePoint{}(Eigen::Vector3d::Zero(), truth[static_cast<std::size_t>(c)].data(),
                           point.data(), r.data());
        const Eigen::Vector3d observed =
            r + 0.01 * Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
        problem.add_residual_block(make_autodiff_block<3, VariableSize<kCamera>, VariableSize<3>>(
                                       CameraFramePoint{}, std::vector<Eigen::Vector3d>{observed}),
                                   {cameras[static_cast<std::size_t>(c)], points.back()});
      }
      if (two_camera_blocks && p % 5 == 4) {
        const auto a = static_cast<std::size_t>(p % 8);
        const auto b = static_cast<std::size_t>((p + 1) % 8);
        Eigen::Vector3d r;
        TwoCameraFramePoint{}(Eigen::Vector3d::Zero(), truth[a].data(), truth[b].data(),
                              point.data(), r.data());
        const Eigen::Vector3d observed =
            r + 0.01 * Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
        problem.add_residual_block(
            make_autodiff_block<3, VariableSize<kCamera>, VariableSize<kCamera>, VariableSize<3>>(
                TwoCameraFramePoint{}, std::vector<Eigen::Vector3d>{observed}),
            {cameras[a], cameras[b], points.back()});
      }
    }
  }
  const SolverSummary a = solve(tight_options(LinearSolver::kSchur), problems[0]);
  const SolverSummary b = solve(tight_options(LinearSolver::kCholesky), problems[1]);
  ASSERT_TRUE(a.is_solution_usable()) << a.message;
  ASSERT_TRUE(b.is_solution_usable()) << b.message;
  EXPECT_NE(a.linear_solver.find("schur complement"), std::string::npos) << a.linear_solver;
  EXPECT_GE(a.num_iterations, 2);
  EXPECT_GT(a.initial_cost, 10.0 * a.final_cost);
  EXPECT_NEAR(a.final_cost, b.final_cost, 1e-9 * b.final_cost);
}

TEST(SchurSolveTest, ThreeRowBlocksReachTheWholeSystemOptimum) {
  expect_three_row_blocks_reach_the_whole_system_optimum<6>();
}

TEST(SchurSolveTest, BlocksOverTwoCamerasAndAPointReachTheWholeSystemOptimum) {
  expect_three_row_blocks_reach_the_whole_system_optimum<6>(true);
}

TEST(SchurSolveTest, ReachesTheWholeSystemOptimumWithARobustLoss) {
  // With a loss the blocks go through their H (not their Jacobian rows) into the elimination.
  const auto huber = make_loss(LossKind::kHuber, 2.0);
  BundleProblem<9> schur = make_bundle<9>(10, 300, 4, 13, true, huber);
  BundleProblem<9> full = make_bundle<9>(10, 300, 4, 13, false, huber);
  Problem& a_problem = schur.problem;
  Problem& b_problem = full.problem;
  const SolverSummary a = solve(tight_options(LinearSolver::kSchur), a_problem);
  const SolverSummary b = solve(tight_options(LinearSolver::kCholesky), b_problem);
  ASSERT_TRUE(a.is_solution_usable()) << a.message;
  ASSERT_TRUE(b.is_solution_usable()) << b.message;
  EXPECT_GT(a.initial_cost, 5.0 * a.final_cost);
  EXPECT_NEAR(a.final_cost, b.final_cost, 1e-9 * b.final_cost);
}

TEST(SchurSolveTest, GaugeFreedomIsHandledByDampingWithoutNonFiniteValues) {
  // Nothing held constant: S has the 7-dimensional null space of bundle adjustment's gauge.
  // Gauss-Newton adds damping only where the undamped system fails; either way every value stays
  // finite and the cost falls.
  for (const Method method : {Method::kLevenbergMarquardt, Method::kGaussNewton}) {
    BundleProblem<9> ba = make_bundle<9>(8, 200, 4, 17, true);
    SolverOptions options = tight_options(LinearSolver::kSchur);
    options.method = method;
    options.max_iterations = 30;
    const SolverSummary summary = solve(options, ba.problem);
    ASSERT_TRUE(summary.is_solution_usable()) << to_string(method) << ": " << summary.message;
    EXPECT_LT(summary.final_cost, 0.1 * summary.initial_cost) << to_string(method);
    for (const double v : ba.problem.all_values()) ASSERT_TRUE(std::isfinite(v));
  }
}

TEST(SchurSolveTest, BitIdenticalForAnyNumberOfThreads) {
  std::vector<double> first;
  for (const int threads : {1, 2}) {
    BundleProblem<9> ba = make_bundle<9>(12, 2000, 5, 5, true);
    SolverOptions options = tight_options(LinearSolver::kSchur);
    options.num_threads = threads;
    options.max_iterations = 10;
    const SolverSummary summary = solve(options, ba.problem);
    ASSERT_TRUE(summary.is_solution_usable()) << summary.message;
    const auto values = ba.problem.all_values();
    if (first.empty()) {
      first.assign(values.begin(), values.end());
    } else {
      ASSERT_EQ(first.size(), values.size());
      for (std::size_t k = 0; k < first.size(); ++k) ASSERT_EQ(first[k], values[k]) << k;
    }
  }
}

TEST(SchurSolveTest, AutoEliminatesTheLargestIndependentGroup) {
  BundleProblem<6> ba = make_bundle<6>(6, 50, 3, 2, false);  // nothing marked
  const SolverSummary summary = solve(tight_options(LinearSolver::kAuto), ba.problem);
  ASSERT_TRUE(summary.is_solution_usable()) << summary.message;
  EXPECT_NE(summary.linear_solver.find("schur complement of 50 eliminated"), std::string::npos)
      << summary.linear_solver;
  EXPECT_EQ(summary.trust_region_growth, 3.0);  // automatic, with the Schur complement

  // A chain of 2-D variables: every block connects two of them, nothing to eliminate.
  Problem chain;
  std::vector<VariableId> ids;
  for (int k = 0; k < 5; ++k) ids.push_back(chain.add_euclidean(Eigen::Vector2d(k, -k)));
  for (int k = 0; k + 1 < 5; ++k) {
    chain.add_residual_block(
        std::make_shared<test::LinearBlock>(
            std::vector<Eigen::MatrixXd>{Eigen::Matrix2d::Identity(), -Eigen::Matrix2d::Identity()},
            Eigen::Vector2d(1.0, 2.0)),
        {ids[static_cast<std::size_t>(k)], ids[static_cast<std::size_t>(k) + 1]});
  }
  const SolverSummary full = solve(tight_options(LinearSolver::kAuto), chain);
  EXPECT_EQ(full.linear_solver.find("schur"), std::string::npos) << full.linear_solver;
  EXPECT_EQ(full.trust_region_growth, 10.0);  // automatic, whole system
  SolverOptions set = tight_options(LinearSolver::kAuto);
  set.max_trust_region_growth = 4.0;
  EXPECT_EQ(solve(set, chain).trust_region_growth, 4.0);
  const SolverSummary forced = solve(tight_options(LinearSolver::kSchur), chain);
  EXPECT_EQ(forced.termination, TerminationType::kFailure);
  EXPECT_EQ(forced.message,
            "linear solver schur: no variables to eliminate (mark them with "
            "Problem::set_eliminable(); every group of free variables of one tangent size has a "
            "residual block connecting two of its members)");

  // Marking two variables that share a block names the block.
  chain.set_eliminable(ids[1]);
  chain.set_eliminable(ids[2]);
  const SolverSummary bad = solve(tight_options(LinearSolver::kAuto), chain);
  EXPECT_EQ(bad.termination, TerminationType::kFailure);
  EXPECT_EQ(bad.message,
            "Schur complement: residual block 1 connects two eliminable variables (1 and 2); the "
            "eliminated variables must not share a block");
}

TEST(SchurSolveTest, ParseLinearSolver) {
  EXPECT_EQ(parse_linear_solver("auto"), LinearSolver::kAuto);
  EXPECT_EQ(parse_linear_solver("schur"), LinearSolver::kSchur);
  EXPECT_EQ(parse_linear_solver("cholesky"), LinearSolver::kCholesky);
  EXPECT_STREQ(to_string(LinearSolver::kSchur), "schur");
  try {
    parse_linear_solver("qr");
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "unknown linear solver 'qr' (valid: auto, schur, cholesky)");
  }
}

}  // namespace
}  // namespace carat
