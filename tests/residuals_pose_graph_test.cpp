// Pose-graph residuals and g2o I/O: analytic Jacobians against numeric ones, parser errors,
// round trips, and end-to-end solves (synthetic city-block graph always, smallGrid3D when the
// real data is present).
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <fstream>
#include <random>
#include <sstream>

#include "carat/base/error.hpp"
#include "carat/residuals/io/g2o_io.hpp"
#include "carat/residuals/pose_graph.hpp"
#include "carat/residuals/pose_prior_block.hpp"
#include "carat/residuals/relative_pose_block.hpp"
#include "carat/sim/pose_graph.hpp"
#include "carat/solver/jacobian_checker.hpp"
#include "carat/solver/solve.hpp"
#include "test_support.hpp"

namespace carat {
namespace {

se3::Matrix6d random_information(std::mt19937_64& rng) {
  std::normal_distribution<double> normal;
  se3::Matrix6d M;
  for (int i = 0; i < 36; ++i) M.data()[i] = normal(rng);
  return M * M.transpose() + se3::Matrix6d::Identity();
}

Eigen::Isometry3d random_pose(std::mt19937_64& rng, double scale) {
  std::normal_distribution<double> normal;
  se3::Vector6d xi;
  for (int i = 0; i < 6; ++i) xi[i] = scale * normal(rng);
  return se3::exp(xi);
}

TEST(RelativePoseBlockTest, JacobiansMatchNumericAtIdentityAndRandomStates) {
  std::mt19937_64 rng(1);
  const Manifold* manifolds[2] = {se3_manifold().get(), se3_manifold().get()};
  for (int trial = 0; trial < 20; ++trial) {
    const double scale = trial == 0 ? 0.0 : 0.7;
    const RelativePoseBlock block(random_pose(rng, scale), random_information(rng));
    double xi[7], xj[7];
    se3::to_storage(random_pose(rng, scale), xi);
    se3::to_storage(random_pose(rng, scale), xj);
    const double* params[2] = {xi, xj};
    const JacobianCheckResult result = check_jacobians(block, manifolds, params);
    EXPECT_TRUE(result.ok) << result.message;
    EXPECT_LT(result.max_rel_error, 1e-7) << result.message;
  }
}

TEST(RelativePoseBlockTest, ZeroAtTheMeasurementAndMatchesWhitening) {
  std::mt19937_64 rng(2);
  const Eigen::Isometry3d T_i = random_pose(rng, 1.0);
  const Eigen::Isometry3d T_i_j = random_pose(rng, 1.0);
  const se3::Matrix6d info = random_information(rng);
  const RelativePoseBlock block(T_i_j, info);
  double xi[7], xj[7];
  se3::to_storage(T_i, xi);
  se3::to_storage(T_i * T_i_j, xj);
  const double* params[2] = {xi, xj};
  EXPECT_LT(block.squared_norm(params), 1e-24);
  EXPECT_LT((block.sqrt_information().transpose() * block.sqrt_information() - info).norm(),
            1e-9 * info.norm());
}

TEST(PosePriorBlockTest, JacobianMatchesNumeric) {
  std::mt19937_64 rng(3);
  const Manifold* manifolds[1] = {se3_manifold().get()};
  for (int trial = 0; trial < 20; ++trial) {
    const PosePriorBlock block(random_pose(rng, 0.8), random_information(rng));
    double x[7];
    se3::to_storage(random_pose(rng, 0.8), x);
    const double* params[1] = {x};
    const JacobianCheckResult result = check_jacobians(block, manifolds, params);
    EXPECT_TRUE(result.ok) << result.message;
  }
}

TEST(PosePriorBlockTest, RejectsIndefiniteInformation) {
  se3::Matrix6d info = se3::Matrix6d::Identity();
  info(2, 2) = -1.0;
  try {
    PosePriorBlock block(Eigen::Isometry3d::Identity(), info);
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "PosePriorBlock: information matrix is not positive definite");
  }
}

std::string edge_line(const char* ids, const char* info) {
  return std::string("EDGE_SE3:QUAT ") + ids + " 1 0 0 0 0 0 1 " + info + "\n";
}
const char* kIdentityInfo = "1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1";

void expect_parse_error(const std::string& text, const std::string& message) {
  std::istringstream in(text);
  try {
    parse_g2o(in, "graph.g2o");
    FAIL() << "expected an error for:\n" << text;
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), message);
  }
}

TEST(G2oTest, MalformedFilesNameTheLineAndTheProblem) {
  const std::string v0 = "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\n";
  const std::string v1 = "VERTEX_SE3:QUAT 1 1 0 0 0 0 0 1\n";
  expect_parse_error("", "graph.g2o: no VERTEX_SE3:QUAT records (empty or not a 3D g2o file)");
  expect_parse_error(v0 + edge_line("0 2", kIdentityInfo),
                     "graph.g2o:2: edge names vertex 2, which is not defined");
  expect_parse_error(v0 + "VERTEX_SE3:QUAT 1 0 0 0 0 0 1\n",
                     "graph.g2o:2: VERTEX_SE3:QUAT needs 8 numbers, found 7");
  expect_parse_error(v0 + "VERTEX_SE3:QUAT 1 0 nan 0 0 0 0 1\n", "graph.g2o:2: y is not finite");
  expect_parse_error(v0 + "VERTEX_SE3:QUAT 1 0 abc 0 0 0 0 1\n",
                     "graph.g2o:2: cannot read y from 'abc'");
  expect_parse_error(v0 + "VERTEX_SE3:QUAT 1 0 0 0 0 0 0 0\n",
                     "graph.g2o:2: quaternion has zero length");
  expect_parse_error(v0 + v0, "graph.g2o:2: vertex 0 was already defined on line 1");
  expect_parse_error(
      v0 + v1 + edge_line("0 1", "1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 -1 0 0 1 0 1"),
      "graph.g2o:3: information matrix: information matrix is not positive definite");
  expect_parse_error(v0 + v1 + "EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 1 0 0\n",
                     "graph.g2o:3: EDGE_SE3:QUAT needs 30 numbers, found 12");
  expect_parse_error(v0 + "PARAMS_SE3OFFSET 0 0 0 0 0 0 0 1\n",
                     "graph.g2o:2: unknown record 'PARAMS_SE3OFFSET'");
  expect_parse_error("VERTEX_SE2 0 0 0 0\n",
                     "graph.g2o:1: 2D record VERTEX_SE2 where a 3D graph is expected");
  expect_parse_error(v0 + v1 + edge_line("1 1", kIdentityInfo),
                     "graph.g2o:3: edge joins vertex 1 to itself");
  expect_parse_error(v0 + "FIX 3\n", "graph.g2o: FIX names vertex 3, which is not defined");
}

TEST(G2oTest, IndefiniteInformationIsRepairedOnlyWhenAsked) {
  // Information V diag(4, -1, 2, 3, 5, 6) V^T with a random orthonormal V: the nearest
  // positive-definite matrix the reader makes is V diag(4, 6e-9, 2, 3, 5, 6) V^T.
  std::mt19937_64 rng(3);
  std::normal_distribution<double> normal;
  se3::Matrix6d random;
  for (int i = 0; i < 36; ++i) random.data()[i] = normal(rng);
  const Eigen::HouseholderQR<se3::Matrix6d> qr(random);
  const se3::Matrix6d V = qr.householderQ();
  se3::Vector6d lambda;
  lambda << 4.0, -1.0, 2.0, 3.0, 5.0, 6.0;
  const se3::Matrix6d indefinite = V * lambda.asDiagonal() * V.transpose();
  std::string info;
  char number[40];
  for (int r = 0; r < 6; ++r) {
    for (int c = r; c < 6; ++c) {
      std::snprintf(number, sizeof(number), "%.17g ", indefinite(r, c));
      info += number;
    }
  }
  const std::string text = "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 1 1 0 0 0 0 0 1\n" +
                           edge_line("0 1", kIdentityInfo) + edge_line("0 1", info.c_str());
  expect_parse_error(
      text, "graph.g2o:4: information matrix: information matrix is not positive definite");

  G2oReadOptions options;
  options.information = InformationRepair::kNearest;
  G2oReadReport report;
  std::istringstream in(text);
  const PoseGraph graph = parse_g2o(in, "graph.g2o", options, &report);
  ASSERT_EQ(graph.edges.size(), 2u);
  EXPECT_EQ(report.repaired_lines, std::vector<std::size_t>{4});
  // A positive-definite matrix is kept bit for bit.
  EXPECT_EQ(graph.edges[0].information, se3::Matrix6d::Identity());
  lambda[1] = 6e-9;
  const se3::Matrix6d expected = V * lambda.asDiagonal() * V.transpose();
  EXPECT_LT((graph.edges[1].information - expected).norm(), 1e-12 * expected.norm());
  EXPECT_EQ(Eigen::LLT<se3::Matrix6d>(graph.edges[1].information).info(), Eigen::Success);

  // Nothing positive to keep: still an error, even when asked to repair.
  std::istringstream negative("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 1 1 0 0 0 0 0 1\n" +
                              edge_line("0 1", "-1 0 0 0 0 0 -1 0 0 0 0 -1 0 0 0 -1 0 0 -1 0 -1"));
  try {
    parse_g2o(negative, "graph.g2o", options);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(),
                 "graph.g2o:3: information matrix has no positive eigenvalue; cannot repair it");
  }
}

TEST(G2oTest, MissingFileAndDirectory) {
  try {
    read_g2o("/nonexistent/graph.g2o");
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "/nonexistent/graph.g2o: no such file");
  }
  const auto dir = test::scratch_dir("g2o_dir");
  EXPECT_THROW(read_g2o(dir), Error);
}

TEST(G2oTest, WriteReadRoundTripIsExact) {
  SyntheticPoseGraphOptions options;
  options.poses_per_lap = 20;
  const SyntheticPoseGraph synthetic = make_synthetic_pose_graph(options);
  const auto path = test::scratch_dir("g2o_roundtrip") / "graph.g2o";
  write_g2o(path, synthetic.graph);
  const PoseGraph back = read_g2o(path);
  ASSERT_EQ(back.vertices.size(), synthetic.graph.vertices.size());
  ASSERT_EQ(back.edges.size(), synthetic.graph.edges.size());
  EXPECT_EQ(back.fixed, synthetic.graph.fixed);
  for (std::size_t i = 0; i < back.vertices.size(); ++i) {
    EXPECT_LT((back.vertices[i].T_world_vertex.matrix() -
               synthetic.graph.vertices[i].T_world_vertex.matrix())
                  .norm(),
              1e-14);
  }
  for (std::size_t i = 0; i < back.edges.size(); ++i) {
    EXPECT_EQ(back.edges[i].information, synthetic.graph.edges[i].information);
  }
  // No temporary file is left next to the output.
  int files = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(path.parent_path()))
    ++files;
  EXPECT_EQ(files, 1);
}

TEST(PoseGraphTest, SyntheticCityBlockIsRecovered) {
  SyntheticPoseGraphOptions options;
  options.poses_per_lap = 150;
  options.laps = 2;
  options.seed = 5;
  SyntheticPoseGraph synthetic = make_synthetic_pose_graph(options);
  const double before = position_rmse(synthetic.graph, synthetic.T_world_truth);
  PoseGraphProblem built = build_pose_graph_problem(synthetic.graph);
  const SolverSummary summary = solve(SolverOptions{}, built.problem);
  ASSERT_EQ(summary.termination, TerminationType::kConvergence) << summary.full_report();
  update_vertices(built, &synthetic.graph);
  const double after = position_rmse(synthetic.graph, synthetic.T_world_truth);
  EXPECT_LT(after, 0.5 * before);
  // At the optimum the cost is about half the chi-square degrees of freedom.
  const double dof =
      static_cast<double>(summary.num_residual_rows) - summary.num_tangent_parameters;
  EXPECT_NEAR(summary.final_cost, 0.5 * dof, 0.2 * 0.5 * dof);
}

TEST(PoseGraphTest, GaussNewtonStartAndConvergenceProbeReachTheSameOptimumSooner) {
  SyntheticPoseGraphOptions options;
  options.poses_per_lap = 100;
  options.laps = 2;
  options.seed = 3;
  const SyntheticPoseGraph synthetic = make_synthetic_pose_graph(options);
  // Defaults: LmStart::kAuto is the Gauss-Newton phase.
  PoseGraphProblem fast = build_pose_graph_problem(synthetic.graph);
  const SolverSummary summary = solve(SolverOptions{}, fast.problem);
  ASSERT_EQ(summary.termination, TerminationType::kConvergence) << summary.full_report();
  EXPECT_EQ(summary.iterations.front().trust_region_radius,
            SolverOptions{}.gauss_newton_phase_radius);
  // The last iteration only confirmed convergence, on the previous factorization.
  EXPECT_TRUE(summary.iterations.back().reused_factorization) << summary.full_report();
  EXPECT_GT(summary.factor_flops, 0.0);
  // Ceres's start, every step factorized afresh: the same optimum, with more factorizations.
  SolverOptions plain;
  plain.lm_start = LmStart::kTrustRegion;
  plain.reuse_factorization = false;
  PoseGraphProblem slow = build_pose_graph_problem(synthetic.graph);
  const SolverSummary reference = solve(plain, slow.problem);
  ASSERT_EQ(reference.termination, TerminationType::kConvergence) << reference.full_report();
  EXPECT_EQ(reference.iterations.front().trust_region_radius, plain.initial_trust_region_radius);
  EXPECT_NEAR(summary.final_cost, reference.final_cost, 1e-9 * reference.final_cost);
  EXPECT_LT(summary.num_iterations - summary.num_reused_factorizations, reference.num_iterations)
      << summary.full_report() << reference.full_report();
}

TEST(PoseGraphTest, FirstVertexIsTheGaugeAndEdgesMustNameVertices) {
  PoseGraph graph;
  graph.vertices.push_back({0, Eigen::Isometry3d::Identity()});
  graph.vertices.push_back({5, Eigen::Isometry3d::Identity()});
  PoseGraph::Edge edge;
  edge.from = 0;
  edge.to = 7;
  graph.edges.push_back(edge);
  try {
    build_pose_graph_problem(graph);
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "pose graph: edge 0 (0 -> 7) names a missing vertex 7");
  }
  graph.edges[0].to = 5;
  const PoseGraphProblem built = build_pose_graph_problem(graph);
  EXPECT_TRUE(built.problem.is_constant(built.vertex_variables[0]));
  EXPECT_FALSE(built.problem.is_constant(built.vertex_variables[1]));
}

TEST(PoseGraphTest, NonRigidVerticesAndMeasurementsAreRefusedByName) {
  PoseGraph graph;
  graph.vertices.push_back({0, Eigen::Isometry3d::Identity()});
  Eigen::Isometry3d scaled = Eigen::Isometry3d::Identity();
  scaled.linear() *= 1.5;
  graph.vertices.push_back({4, scaled});
  PoseGraph::Edge edge;
  edge.from = 0;
  edge.to = 4;
  graph.edges.push_back(edge);
  EXPECT_EQ(test::error_of([&] { build_pose_graph_problem(graph); }),
            "pose graph: vertex 4: the pose has a rotation block that is not orthonormal (scaled "
            "or sheared: |R^T R - I| > 1e-6)");
  graph.vertices[1].T_world_vertex = Eigen::Isometry3d::Identity();
  graph.edges[0].T_from_to.linear()(0, 0) = -1.0;
  EXPECT_EQ(test::error_of([&] { build_pose_graph_problem(graph); }),
            "pose graph: edge 0 (0 -> 4): the measurement has a reflection, not a rotation (det "
            "R < 0)");
}

TEST(PoseGraphTest, SmallGrid3DConverges) {
  CARAT_REQUIRE_DATA("posegraph/smallGrid3D.g2o");
  PoseGraph graph = read_g2o(test::data_dir() / "posegraph/smallGrid3D.g2o");
  ASSERT_EQ(graph.vertices.size(), 125u);
  ASSERT_EQ(graph.edges.size(), 297u);
  PoseGraphProblem built = build_pose_graph_problem(graph);
  SolverOptions options;
  options.max_iterations = 100;
  const SolverSummary lm = solve(options, built.problem);
  ASSERT_EQ(lm.termination, TerminationType::kConvergence) << lm.full_report();
  EXPECT_LT(lm.final_cost, 1e-2 * lm.initial_cost);
  // Gauss-Newton from the same start reaches the same minimum.
  PoseGraphProblem again = build_pose_graph_problem(graph);
  options.method = Method::kGaussNewton;
  const SolverSummary gn = solve(options, again.problem);
  ASSERT_NE(gn.termination, TerminationType::kFailure) << gn.message;
  EXPECT_NEAR(gn.final_cost, lm.final_cost, 1e-6 * lm.final_cost);
}

TEST(PoseGraphTest, DeterministicAcrossThreadCounts) {
  SyntheticPoseGraphOptions options;
  options.poses_per_lap = 100;
  const SyntheticPoseGraph synthetic = make_synthetic_pose_graph(options);
  std::vector<double> reference;
  for (int threads : {1, 2}) {
    PoseGraphProblem built = build_pose_graph_problem(synthetic.graph);
    SolverOptions solver_options;
    solver_options.num_threads = threads;
    solve(solver_options, built.problem);
    const auto values = built.problem.all_values();
    if (reference.empty()) {
      reference.assign(values.begin(), values.end());
    } else {
      EXPECT_TRUE(std::equal(values.begin(), values.end(), reference.begin()));
    }
  }
}

}  // namespace
}  // namespace carat

namespace carat {
namespace {

TEST(PoseGraphProblemTest, PartsNotLinkedToAFixedVertexAreAnError) {
  PoseGraph graph;
  for (int i = 0; i < 5; ++i) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation().x() = i;
    graph.vertices.push_back({i, T});
  }
  Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
  step.translation().x() = 1.0;
  graph.edges.push_back({0, 1, step, se3::Matrix6d::Identity()});
  graph.edges.push_back({2, 3, step, se3::Matrix6d::Identity()});  // 2-3 and 4 float
  try {
    build_pose_graph_problem(graph);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(),
                 "pose graph: 3 vertices in 2 disconnected part(s) are not linked to a fixed "
                 "vertex (e.g. vertex 2), so their poses are undetermined; add edges or FIX "
                 "records");
  }
  // A FIX in each part, or an explicit opt-out, makes it acceptable.
  graph.fixed = {0, 2, 4};
  EXPECT_NO_THROW(build_pose_graph_problem(graph));
  graph.fixed.clear();
  PoseGraphProblemOptions options;
  options.allow_unanchored = true;
  EXPECT_NO_THROW(build_pose_graph_problem(graph, options));
}

}  // namespace
}  // namespace carat
