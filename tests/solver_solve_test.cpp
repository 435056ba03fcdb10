// The solver: problem validation, LM/GN on problems with known optima, robust losses,
// constant variables, determinism across thread counts, indefinite systems, the sparse
// assembly against a dense reference.
#include "carat/solver/solve.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <vector>

#include "../solver/src/block_evaluator.hpp"
#include "../solver/src/sparse_system.hpp"
#include "carat/base/error.hpp"
#include "carat/solver/autodiff_block.hpp"
#include "carat/solver/block_source.hpp"
#include "carat/solver/evaluate.hpp"
#include "carat/solver/loss_function.hpp"
#include "carat/solver/problem.hpp"
#include "carat/solver/solver_options.hpp"
#include "curve_fit_problem.hpp"
#include "solver_test_blocks.hpp"
#include "test_support.hpp"

namespace carat {
namespace {

using test::LinearBlock;
using test::RosenbrockBlock;

/// A random sparse linear least-squares problem: `n` Euclidean variables of size 3 (and 2),
/// chain plus random extra blocks. Returns the problem and the dense (J, y) for reference.
struct RandomLinear {
  Problem problem;
  Eigen::MatrixXd J;  // rows x total dims (variable order)
  Eigen::VectorXd y;
};

RandomLinear make_random_linear(int n, std::uint64_t seed) {
  RandomLinear out;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  std::vector<int> dims, offsets;
  int total = 0;
  for (int v = 0; v < n; ++v) {
    const int d = (v % 3 == 0) ? 2 : 3;
    out.problem.add_euclidean(Eigen::VectorXd::Zero(d));
    dims.push_back(d);
    offsets.push_back(total);
    total += d;
  }
  std::vector<Eigen::MatrixXd> rowsJ;
  std::vector<double> ys;
  auto add = [&](std::vector<int> vars, int rows) {
    std::vector<Eigen::MatrixXd> A;
    Eigen::VectorXd y(rows);
    for (int i = 0; i < rows; ++i) y[i] = normal(rng);
    Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(rows, total);
    std::vector<VariableId> ids;
    for (int v : vars) {
      Eigen::MatrixXd a(rows, dims[static_cast<std::size_t>(v)]);
      for (int i = 0; i < a.size(); ++i) a.data()[i] = normal(rng);
      dense.block(0, offsets[static_cast<std::size_t>(v)], rows, a.cols()) = a;
      A.push_back(a);
      ids.push_back(VariableId{v});
    }
    out.problem.add_residual_block(std::make_shared<LinearBlock>(A, y), ids);
    rowsJ.push_back(dense);
    for (int i = 0; i < rows; ++i) ys.push_back(y[i]);
  };
  for (int v = 0; v < n; ++v) add({v}, 3);
  for (int v = 0; v + 1 < n; ++v) add({v, v + 1}, 4);
  std::uniform_int_distribution<int> pick(0, n - 1);
  for (int k = 0; k < n; ++k) {
    const int a = pick(rng), b = pick(rng);
    if (a != b) add({a, b}, 5);
  }
  int total_rows = 0;
  for (const auto& m : rowsJ) total_rows += static_cast<int>(m.rows());
  out.J.resize(total_rows, total);
  int r = 0;
  for (const auto& m : rowsJ) {
    out.J.middleRows(r, m.rows()) = m;
    r += static_cast<int>(m.rows());
  }
  out.y = Eigen::Map<Eigen::VectorXd>(ys.data(), static_cast<Eigen::Index>(ys.size()));
  return out;
}

TEST(SolveTest, LinearLeastSquaresReachesTheDenseSolution) {
  RandomLinear lin = make_random_linear(40, 7);
  const Eigen::VectorXd expected =
      (lin.J.transpose() * lin.J).ldlt().solve(lin.J.transpose() * lin.y);
  for (Method method : {Method::kLevenbergMarquardt, Method::kGaussNewton}) {
    Problem problem = lin.problem;
    SolverOptions options;
    options.method = method;
    options.function_tolerance = 1e-14;
    options.gradient_tolerance = 1e-12;
    const SolverSummary summary = solve(options, problem);
    ASSERT_EQ(summary.termination, TerminationType::kConvergence) << summary.message;
    const auto x = problem.all_values();
    const Eigen::Map<const Eigen::VectorXd> xv(x.data(), static_cast<Eigen::Index>(x.size()));
    EXPECT_LT((xv - expected).norm() / expected.norm(), 1e-8) << summary.full_report();
    EXPECT_NEAR(summary.final_cost, 0.5 * (lin.J * expected - lin.y).squaredNorm(),
                1e-9 * summary.final_cost);
  }
}

TEST(SolveTest, AssemblyMatchesDenseNormalEquations) {
  RandomLinear lin = make_random_linear(25, 3);
  for (Ordering ordering : {Ordering::kAmd, Ordering::kMetis, Ordering::kAuto}) {
    internal::SparseSystem system(lin.problem, ordering);
    internal::BlockEvaluator evaluator(lin.problem);
    std::vector<double> values(lin.problem.all_values().begin(), lin.problem.all_values().end());
    evaluator.bind(0, values.data());
    internal::BlockLinearizations blocks;
    evaluator.allocate(&blocks);
    std::string error;
    ASSERT_TRUE(evaluator.linearize(0, &blocks, &error)) << error;
    Eigen::VectorXd gradient;
    system.assemble(blocks, &gradient);
    // Solve H x = -g through CHOLMOD and compare with the dense solution (permuted layout).
    ASSERT_TRUE(system.factorize(Eigen::VectorXd::Zero(system.size())));
    Eigen::VectorXd delta;
    system.solve(-gradient, &delta);
    const Eigen::VectorXd expected =
        (lin.J.transpose() * lin.J).ldlt().solve(lin.J.transpose() * lin.y);
    Eigen::VectorXd x(expected.size());
    Eigen::VectorXd g_dense = -lin.J.transpose() * lin.y;  // gradient J^T r at x = 0
    Eigen::VectorXd g_perm(expected.size());
    for (int v = 0, offset = 0; v < lin.problem.num_variables(); ++v) {
      const int d = lin.problem.manifold(VariableId{v}).tangent_size();
      const int o = system.variable_offset()[static_cast<std::size_t>(v)];
      x.segment(offset, d) = delta.segment(o, d);
      g_perm.segment(offset, d) = gradient.segment(o, d);
      offset += d;
    }
    EXPECT_LT((g_perm - g_dense).norm(), 1e-12 * g_dense.norm());
    EXPECT_LT((x - expected).norm(), 1e-9 * expected.norm());
    const Eigen::VectorXd diag = system.diagonal();
    EXPECT_NEAR(diag.sum(), (lin.J.transpose() * lin.J).trace(), 1e-9 * diag.sum());

    // H v through the stored lower triangle equals the dense product (in the permuted layout).
    std::mt19937_64 rng(11);
    std::normal_distribution<double> normal;
    Eigen::VectorXd v_dense(expected.size()), v_perm(expected.size());
    for (Eigen::Index k = 0; k < v_dense.size(); ++k) v_dense[k] = normal(rng);
    for (int v = 0, offset = 0; v < lin.problem.num_variables(); ++v) {
      const int d = lin.problem.manifold(VariableId{v}).tangent_size();
      v_perm.segment(system.variable_offset()[static_cast<std::size_t>(v)], d) =
          v_dense.segment(offset, d);
      offset += d;
    }
    Eigen::VectorXd hv_perm;
    system.multiply(v_perm, &hv_perm);
    const Eigen::VectorXd hv_dense = lin.J.transpose() * (lin.J * v_dense);
    for (int v = 0, offset = 0; v < lin.problem.num_variables(); ++v) {
      const int d = lin.problem.manifold(VariableId{v}).tangent_size();
      const int o = system.variable_offset()[static_cast<std::size_t>(v)];
      EXPECT_LT((hv_perm.segment(o, d) - hv_dense.segment(offset, d)).norm(),
                1e-12 * hv_dense.norm());
      offset += d;
    }

    // A damped factorization leaves the assembled (undamped) matrix exactly as it was.
    ASSERT_TRUE(system.factorize(Eigen::VectorXd::Constant(system.size(), 0.37)));
    EXPECT_EQ(system.diagonal(), diag);
    Eigen::VectorXd hv_after;
    system.multiply(v_perm, &hv_after);
    EXPECT_EQ(hv_after, hv_perm);
  }
}

TEST(SolveTest, LinearizingInRunsAssemblesWhatAllBlocksAtOnceDo) {
  // 70,000 one-row blocks over pairs of 300 scalars (Cauchy on every fifth): more than two of
  // SparseSystem::linearize()'s runs.
  Problem problem;
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal;
  constexpr int kVariables = 300;
  constexpr int kBlocks = 70000;
  for (int v = 0; v < kVariables; ++v)
    problem.add_euclidean(Eigen::VectorXd::Constant(1, normal(rng)));
  const auto loss = std::make_shared<CauchyLoss>(0.5);
  std::uniform_int_distribution<int> pick(0, kVariables - 1);
  for (int k = 0; k < kBlocks; ++k) {
    const int a = pick(rng);
    const int b = (a + 1 + pick(rng) % (kVariables - 1)) % kVariables;
    problem.add_residual_block(
        std::make_shared<LinearBlock>(
            std::vector<Eigen::MatrixXd>{Eigen::MatrixXd::Constant(1, 1, normal(rng)),
                                         Eigen::MatrixXd::Constant(1, 1, normal(rng))},
            Eigen::VectorXd::Constant(1, normal(rng))),
        {VariableId{a}, VariableId{b}}, k % 5 == 0 ? loss : nullptr);
  }
  internal::BlockEvaluator evaluator(problem);
  std::vector<double> values(problem.all_values().begin(), problem.all_values().end());
  evaluator.bind(0, values.data());
  internal::SparseSystem runs(problem, Ordering::kAmd);
  Eigen::VectorXd run_gradient;
  const internal::LinearizeReport report = runs.linearize(evaluator, 0, &run_gradient);
  ASSERT_TRUE(report.ok) << report.error;

  internal::SparseSystem whole(problem, Ordering::kAmd);
  internal::BlockLinearizations blocks;
  evaluator.allocate(&blocks);
  std::string error;
  ASSERT_TRUE(evaluator.linearize(0, &blocks, &error)) << error;
  Eigen::VectorXd gradient;
  whole.assemble(blocks, &gradient);
  double cost = 0.0;
  for (const double c : blocks.cost) cost += c;

  EXPECT_EQ(report.cost, cost);
  ASSERT_EQ(run_gradient.size(), gradient.size());
  EXPECT_TRUE((run_gradient.array() == gradient.array()).all());
  EXPECT_TRUE((runs.diagonal().array() == whole.diagonal().array()).all());
  Eigen::VectorXd x(runs.size()), hx_runs, hx_whole;
  for (Eigen::Index k = 0; k < x.size(); ++k) x[k] = normal(rng);
  runs.multiply(x, &hx_runs);
  whole.multiply(x, &hx_whole);
  EXPECT_TRUE((hx_runs.array() == hx_whole.array()).all());

  // A block that is not finite in the last run is the one named, as for all blocks at once.
  problem.add_residual_block(
      std::make_shared<LinearBlock>(
          std::vector<Eigen::MatrixXd>{Eigen::MatrixXd::Ones(1, 1), Eigen::MatrixXd::Ones(1, 1)},
          Eigen::VectorXd::Constant(1, std::numeric_limits<double>::quiet_NaN())),
      {VariableId{0}, VariableId{1}});
  internal::BlockEvaluator bad_evaluator(problem);
  bad_evaluator.bind(0, values.data());
  internal::SparseSystem bad(problem, Ordering::kAmd);
  const internal::LinearizeReport failed = bad.linearize(bad_evaluator, 0, &run_gradient);
  EXPECT_FALSE(failed.ok);
  EXPECT_THAT(failed.error, testing::StartsWith("residual block 70000: row 0 is not finite"));
  internal::BlockLinearizations bad_blocks;
  bad_evaluator.allocate(&bad_blocks);
  EXPECT_FALSE(bad_evaluator.linearize(0, &bad_blocks, &error));
  EXPECT_EQ(failed.error, error);
}

TEST(SolveTest, RosenbrockFromTheClassicStart) {
  Problem problem;
  const VariableId x = problem.add_euclidean(Eigen::Vector2d(-1.2, 1.0));
  problem.add_residual_block(std::make_shared<RosenbrockBlock>(), {x});
  SolverOptions options;
  options.max_iterations = 100;
  options.function_tolerance = 1e-15;
  options.gradient_tolerance = 1e-14;
  const SolverSummary summary = solve(options, problem);
  EXPECT_EQ(summary.termination, TerminationType::kConvergence) << summary.full_report();
  EXPECT_NEAR(problem.value(x)[0], 1.0, 1e-8);
  EXPECT_NEAR(problem.value(x)[1], 1.0, 1e-8);
  EXPECT_LT(summary.final_cost, 1e-16);
  EXPECT_GT(summary.num_successful_steps, 3);
}

TEST(SolveTest, EvaluationCallbackSaysWhatEachPassIsForAndWhenTheSolveLikelyEnds) {
  Problem problem;
  const VariableId mc = problem.add_euclidean(Eigen::Vector2d(0.0, 0.0));
  problem.add_residual_block(
      make_autodiff_block<1, VariableSize<2>>(test::ExpResidual{}, test::curve_data(200, 3)), {mc});
  std::vector<EvaluationHint> hints;
  SolverOptions options;
  options.evaluation_callback = [&](const EvaluationHint& hint) { hints.push_back(hint); };
  const SolverSummary summary = solve(options, problem);
  ASSERT_EQ(summary.termination, TerminationType::kConvergence) << summary.full_report();
  ASSERT_NE(summary.message.find("function tolerance"), std::string::npos) << summary.message;
  ASSERT_GE(hints.size(), 3u);
  EXPECT_TRUE(hints.front().jacobians);  // the start is linearized
  int linearizations = 0, cost_passes = 0, final_passes = 0;
  for (const EvaluationHint& hint : hints) {
    linearizations += hint.jacobians;
    cost_passes += !hint.jacobians;
    final_passes += !hint.jacobians && hint.likely_final;
    EXPECT_FALSE(hint.jacobians && hint.likely_final);
  }
  // The step that met the tolerance was announced, and only in the last iteration (its solved
  // step and, in an accelerated tail, Anderson's combination); it was not linearized, every
  // other accepted step was.
  EXPECT_FALSE(hints.back().jacobians);
  EXPECT_TRUE(hints.back().likely_final);
  EXPECT_GE(final_passes, 1);
  const auto last_linearization = std::find_if(hints.rbegin(), hints.rend(),
                                               [](const EvaluationHint& h) { return h.jacobians; });
  EXPECT_EQ(std::count_if(hints.rbegin(), last_linearization,
                          [](const EvaluationHint& h) { return h.likely_final; }),
            final_passes);
  // At least one cost pass an iteration (a step on a reused factorization that is refused
  // is followed by a fresh one in the same iteration).
  EXPECT_GE(cost_passes, static_cast<int>(summary.iterations.size()) - 1);
  EXPECT_EQ(linearizations, summary.num_successful_steps);  // the start's, less the last step's
}

TEST(SolveTest, IterationCallbackSeesEveryRowAndCanAbort) {
  struct Seen {
    int iteration;
    double cost;
    Eigen::Vector2d x;
  };
  const auto run = [](int abort_at, bool update_state, std::vector<Seen>* seen,
                      Eigen::Vector2d* final_x) {
    Problem problem;
    const VariableId x = problem.add_euclidean(Eigen::Vector2d(-1.2, 1.0));
    problem.add_residual_block(std::make_shared<RosenbrockBlock>(), {x});
    SolverOptions options;
    options.max_iterations = 100;
    options.update_state_every_iteration = update_state;
    options.iteration_callback = [&](const IterationSummary& row) {
      seen->push_back(
          {row.iteration, row.cost, Eigen::Vector2d(problem.value(x)[0], problem.value(x)[1])});
      return row.iteration == abort_at ? CallbackResult::kAbort : CallbackResult::kContinue;
    };
    const SolverSummary summary = solve(options, problem);
    *final_x = Eigen::Vector2d(problem.value(x)[0], problem.value(x)[1]);
    return summary;
  };
  std::vector<Seen> seen;
  Eigen::Vector2d final_x;
  const SolverSummary full = run(-1, true, &seen, &final_x);
  ASSERT_EQ(full.termination, TerminationType::kConvergence);
  ASSERT_EQ(seen.size(), full.iterations.size());
  for (std::size_t k = 0; k < seen.size(); ++k) {
    EXPECT_EQ(seen[k].iteration, full.iterations[k].iteration);
    EXPECT_EQ(seen[k].cost, full.iterations[k].cost);
  }
  EXPECT_EQ(seen.back().x, final_x);  // the state at the last call is the result

  // Abort at the first accepted step: the solve stops there and keeps that iterate.
  int first_step = 1;
  while (!full.iterations[static_cast<std::size_t>(first_step)].step_is_successful) ++first_step;
  seen.clear();
  const SolverSummary aborted = run(first_step, true, &seen, &final_x);
  EXPECT_EQ(aborted.termination, TerminationType::kUserAbort);
  EXPECT_EQ(aborted.message, "the iteration callback asked to stop");
  EXPECT_STREQ(to_string(aborted.termination), "USER_ABORT");
  ASSERT_EQ(seen.size(), static_cast<std::size_t>(first_step + 1));
  EXPECT_EQ(aborted.iterations.size(), seen.size());
  EXPECT_EQ(final_x, seen.back().x);  // the last accepted iterate is kept
  EXPECT_EQ(aborted.final_cost, full.iterations[static_cast<std::size_t>(first_step)].cost);
  EXPECT_NE(final_x, Eigen::Vector2d(-1.2, 1.0));

  seen.clear();
  const SolverSummary at_start = run(0, false, &seen, &final_x);
  EXPECT_EQ(at_start.termination, TerminationType::kUserAbort);
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_EQ(seen[0].x, Eigen::Vector2d(-1.2, 1.0));
  EXPECT_EQ(final_x, Eigen::Vector2d(-1.2, 1.0));

  // Without update_state_every_iteration the variables keep the start until the solve ends.
  seen.clear();
  run(-1, false, &seen, &final_x);
  for (const Seen& s : seen) EXPECT_EQ(s.x, Eigen::Vector2d(-1.2, 1.0));
}

TEST(SolveTest, ConstantVariablesDoNotMove) {
  Problem problem;
  const VariableId a = problem.add_euclidean(Eigen::Vector2d(1.0, 2.0));
  const VariableId b = problem.add_euclidean(Eigen::Vector2d(0.0, 0.0));
  // r = b - a - (3, 4): with a fixed, b must become a + (3, 4).
  std::vector<Eigen::MatrixXd> A = {-Eigen::MatrixXd::Identity(2, 2),
                                    Eigen::MatrixXd::Identity(2, 2)};
  problem.add_residual_block(std::make_shared<LinearBlock>(A, Eigen::Vector2d(3.0, 4.0)), {a, b});
  problem.set_constant(a);
  SolverOptions options;
  options.function_tolerance = 1e-15;
  options.parameter_tolerance = 1e-15;
  const SolverSummary summary = solve(options, problem);
  ASSERT_EQ(summary.termination, TerminationType::kConvergence) << summary.message;
  EXPECT_EQ(problem.value(a)[0], 1.0);
  EXPECT_EQ(problem.value(a)[1], 2.0);
  EXPECT_NEAR(problem.value(b)[0], 4.0, 1e-9);
  EXPECT_NEAR(problem.value(b)[1], 6.0, 1e-9);
  EXPECT_EQ(summary.num_tangent_parameters, 2);
}

TEST(SolveTest, AllConstantIsConvergedWithoutSteps) {
  Problem problem;
  const VariableId a = problem.add_euclidean(Eigen::Vector2d(1.0, 2.0));
  problem.add_residual_block(std::make_shared<RosenbrockBlock>(), {a});
  problem.set_constant(a);
  const SolverSummary summary = solve(SolverOptions{}, problem);
  EXPECT_EQ(summary.termination, TerminationType::kConvergence);
  EXPECT_NE(summary.message.find("no free variables"), std::string::npos);
  EXPECT_EQ(summary.num_iterations, 0);
}

TEST(SolveTest, RobustLossesDownweightAnOutlier) {
  // Estimate a scalar mean of 10 inliers near 1 and one outlier at 100.
  auto run = [](std::shared_ptr<const LossFunction> loss) {
    Problem problem;
    const VariableId m = problem.add_euclidean(Eigen::VectorXd::Constant(1, 0.0));
    for (int i = 0; i < 10; ++i) {
      problem.add_residual_block(
          std::make_shared<LinearBlock>(std::vector<Eigen::MatrixXd>{Eigen::MatrixXd::Ones(1, 1)},
                                        Eigen::VectorXd::Constant(1, 1.0 + 0.01 * (i - 4.5))),
          {m}, loss);
    }
    problem.add_residual_block(
        std::make_shared<LinearBlock>(std::vector<Eigen::MatrixXd>{Eigen::MatrixXd::Ones(1, 1)},
                                      Eigen::VectorXd::Constant(1, 100.0)),
        {m}, loss);
    SolverOptions options;
    options.max_iterations = 200;
    options.function_tolerance = 1e-15;
    options.parameter_tolerance = 1e-15;
    const SolverSummary summary = solve(options, problem);
    EXPECT_NE(summary.termination, TerminationType::kFailure) << summary.message;
    return problem.value(m)[0];
  };
  // Without a loss the cost at the mean is ~4455: the last steps change it by less than its
  // rounding, and are taken on the model's word (a cost comparison alone stalls near 1e-8).
  EXPECT_NEAR(run(nullptr), (10.0 + 100.0) / 11.0, 1e-12);
  EXPECT_NEAR(run(std::make_shared<HuberLoss>(0.1)), 1.0, 0.02);
  EXPECT_NEAR(run(std::make_shared<CauchyLoss>(0.1)), 1.0, 1e-3);
}

TEST(LossTest, DerivativesMatchFiniteDifferences) {
  const HuberLoss huber(0.7);
  const CauchyLoss cauchy(1.3);
  for (const LossFunction* loss :
       {static_cast<const LossFunction*>(&huber), static_cast<const LossFunction*>(&cauchy)}) {
    for (double s : {0.01, 0.3, 0.45, 0.6, 2.0, 50.0}) {  // away from Huber's kink at 0.49
      const double h = 1e-6 * std::max(1.0, s);
      const LossValue v = loss->evaluate(s);
      const LossValue p = loss->evaluate(s + h);
      const LossValue m = loss->evaluate(s - h);
      EXPECT_NEAR(v.rho1, (p.rho - m.rho) / (2 * h), 1e-6) << loss->name() << " s=" << s;
      EXPECT_NEAR(v.rho2, (p.rho1 - m.rho1) / (2 * h), 1e-5) << loss->name() << " s=" << s;
    }
    EXPECT_DOUBLE_EQ(loss->evaluate(0.0).rho, 0.0);
    EXPECT_DOUBLE_EQ(loss->evaluate(0.0).rho1, 1.0);
  }
  EXPECT_THROW(HuberLoss(0.0), Error);
  EXPECT_THROW(CauchyLoss(-1.0), Error);
  // Scales whose square overflows or underflows would turn the loss into inf or NaN.
  for (double bad : {1e300, 1e-300, std::nan(""), HUGE_VAL}) {
    EXPECT_THROW(HuberLoss{bad}, Error) << bad;
    EXPECT_THROW(CauchyLoss{bad}, Error) << bad;
  }
  const LossValue far = CauchyLoss(1e150).evaluate(1e300);
  EXPECT_TRUE(std::isfinite(far.rho) && std::isfinite(far.rho1) && std::isfinite(far.rho2));
}

TEST(LossTest, ExcessLossIsPlainUpToTheOffsetAndTheInnerLossBeyond) {
  const auto cauchy = std::make_shared<CauchyLoss>(1.3);
  const ExcessLoss excess(5.0, cauchy);
  EXPECT_EQ(excess.offset(), 5.0);
  for (double s : {0.0, 2.0, 5.0}) {  // at and below the offset: s itself
    const LossValue v = excess.evaluate(s);
    EXPECT_EQ(v.rho, s);
    EXPECT_EQ(v.rho1, 1.0);
    EXPECT_EQ(v.rho2, 0.0);
  }
  for (double s : {5.5, 7.0, 60.0}) {  // beyond: offset + inner(s - offset), inner's derivatives
    const LossValue v = excess.evaluate(s);
    const LossValue inner = cauchy->evaluate(s - 5.0);
    EXPECT_DOUBLE_EQ(v.rho, 5.0 + inner.rho);
    EXPECT_EQ(v.rho1, inner.rho1);
    EXPECT_EQ(v.rho2, inner.rho2);
    const double h = 1e-6 * s;
    EXPECT_NEAR(v.rho1, (excess.evaluate(s + h).rho - excess.evaluate(s - h).rho) / (2 * h), 1e-6);
  }
  // Continuous with a continuous slope at the offset.
  EXPECT_NEAR(excess.evaluate(5.0 + 1e-9).rho, 5.0, 1e-8);
  EXPECT_NEAR(excess.evaluate(5.0 + 1e-9).rho1, 1.0, 1e-8);
  EXPECT_THAT([&] { ExcessLoss(-1.0, cauchy); },
              ::testing::ThrowsMessage<Error>(
                  ::testing::HasSubstr("offset must be finite and >= 0, got -1")));
  EXPECT_THROW(ExcessLoss(std::numeric_limits<double>::infinity(), cauchy), Error);
  EXPECT_THAT([&] { ExcessLoss(1.0, nullptr); },
              ::testing::ThrowsMessage<Error>(::testing::HasSubstr("inner loss is null")));
}

TEST(LossTest, KindNamesRoundTripAndMakeTheirLoss) {
  for (LossKind kind : {LossKind::kNone, LossKind::kHuber, LossKind::kCauchy}) {
    EXPECT_EQ(parse_loss_kind(to_string(kind)), kind) << to_string(kind);
  }
  EXPECT_STREQ(to_string(LossKind::kNone), "none");
  EXPECT_EQ(make_loss(LossKind::kNone, 2.0), nullptr);
  const auto huber = make_loss(LossKind::kHuber, 2.0);
  ASSERT_NE(huber, nullptr);
  EXPECT_STREQ(huber->name(), to_string(LossKind::kHuber));
  EXPECT_EQ(huber->evaluate(9.0).rho, HuberLoss(2.0).evaluate(9.0).rho);  // beyond delta^2 = 4
  const auto cauchy = make_loss(LossKind::kCauchy, 2.0);
  ASSERT_NE(cauchy, nullptr);
  EXPECT_STREQ(cauchy->name(), to_string(LossKind::kCauchy));
  EXPECT_EQ(cauchy->evaluate(9.0).rho, CauchyLoss(2.0).evaluate(9.0).rho);
  EXPECT_THROW(make_loss(LossKind::kCauchy, 0.0), Error);  // as the loss's own constructor
  EXPECT_EQ(test::error_of([] { parse_loss_kind("tukey"); }),
            "unknown loss 'tukey' (valid: none, huber, cauchy)");
  EXPECT_EQ(test::error_of([] { parse_loss_kind("huber\n"); }),
            "unknown loss 'huber?' (valid: none, huber, cauchy)");
}

TEST(SolveTest, BitIdenticalAcrossThreadCounts) {
  RandomLinear lin = make_random_linear(300, 11);
  // Make it nonlinear: add a Rosenbrock variable too.
  const VariableId r = lin.problem.add_euclidean(Eigen::Vector2d(-1.2, 1.0));
  lin.problem.add_residual_block(std::make_shared<RosenbrockBlock>(), {r});
  std::vector<double> reference;
  double reference_cost = 0.0;
  for (int threads : {1, 2, 4}) {
    Problem problem = lin.problem;
    SolverOptions options;
    options.num_threads = threads;
    options.max_iterations = 30;
    const SolverSummary summary = solve(options, problem);
    ASSERT_NE(summary.termination, TerminationType::kFailure);
    const auto values = problem.all_values();
    if (reference.empty()) {
      reference.assign(values.begin(), values.end());
      reference_cost = summary.final_cost;
      continue;
    }
    EXPECT_EQ(summary.final_cost, reference_cost) << threads << " threads";
    ASSERT_EQ(values.size(), reference.size());
    for (std::size_t i = 0; i < values.size(); ++i)
      ASSERT_EQ(values[i], reference[i]) << "value " << i << ", " << threads << " threads";
  }
}

TEST(SolveTest, SingularSystemIsHandledAndReported) {
  // Two variables, one relative block, no gauge: H is singular (rank 2 of 4).
  auto make = [] {
    Problem problem;
    const VariableId a = problem.add_euclidean(Eigen::Vector2d(0.0, 0.0));
    const VariableId b = problem.add_euclidean(Eigen::Vector2d(0.0, 0.0));
    std::vector<Eigen::MatrixXd> A = {-Eigen::MatrixXd::Identity(2, 2),
                                      Eigen::MatrixXd::Identity(2, 2)};
    problem.add_residual_block(std::make_shared<LinearBlock>(A, Eigen::Vector2d(1.0, -1.0)),
                               {a, b});
    return problem;
  };
  {
    Problem problem = make();
    SolverOptions options;
    options.method = Method::kGaussNewton;
    const SolverSummary summary = solve(options, problem);
    // GN cannot factorize H alone; it raises the damping and still reaches zero cost.
    EXPECT_GT(summary.num_linear_solver_failures, 0);
    EXPECT_NE(summary.termination, TerminationType::kFailure) << summary.message;
    EXPECT_LT(summary.final_cost, 1e-12);
    for (double v : problem.all_values()) EXPECT_TRUE(std::isfinite(v));
  }
  {
    Problem problem = make();
    const SolverSummary summary = solve(SolverOptions{}, problem);  // LM's damping regularizes
    EXPECT_EQ(summary.termination, TerminationType::kConvergence) << summary.message;
    EXPECT_LT(summary.final_cost, 1e-12);
  }
}

/// A block with a negative definite "Gauss-Newton" matrix cannot exist (H = J^T J), but a
/// robust loss can make a block's H indefinite only through the documented correction, which
/// is dropped when unsafe. Check that Cauchy far in its tail keeps H positive semidefinite.
TEST(SolveTest, CauchyTailKeepsTheSystemUsable) {
  Problem problem;
  const VariableId m = problem.add_euclidean(Eigen::VectorXd::Constant(1, 50.0));
  problem.add_residual_block(
      std::make_shared<LinearBlock>(std::vector<Eigen::MatrixXd>{Eigen::MatrixXd::Ones(1, 1)},
                                    Eigen::VectorXd::Constant(1, 0.0)),
      {m}, std::make_shared<CauchyLoss>(1.0));
  SolverOptions options;
  options.max_iterations = 500;
  const SolverSummary summary = solve(options, problem);
  EXPECT_NE(summary.termination, TerminationType::kFailure) << summary.message;
  EXPECT_LT(std::abs(problem.value(m)[0]), 1e-3) << summary.full_report();
}

TEST(SolveTest, NonFiniteInitialCostIsAFailureThatKeepsTheValues) {
  class NanBlock final : public ResidualBlock {
   public:
    int num_rows() const override { return 1; }
    std::span<const int> tangent_dims() const override { return dims_; }
    void evaluate_rows(ParameterPointers, std::span<const int> rows, double* r,
                       double* J) const override {
      for (std::size_t k = 0; k < rows.size(); ++k) {
        r[k] = std::nan("");
        if (J) J[k] = 1.0;
      }
    }
    std::size_t memory_bytes() const override { return 0; }

   private:
    std::array<int, 1> dims_{1};
  };
  Problem problem;
  const VariableId a = problem.add_euclidean(Eigen::VectorXd::Constant(1, 3.0));
  problem.add_residual_block(std::make_shared<NanBlock>(), {a});
  const SolverSummary summary = solve(SolverOptions{}, problem);
  EXPECT_EQ(summary.termination, TerminationType::kFailure);
  EXPECT_EQ(summary.message, "residual block 0: row 0 is not finite (residual nan)");
  EXPECT_EQ(problem.value(a)[0], 3.0);
}

TEST(SolveTest, TheLastPermittedIterateIsNotRelinearized) {
  // A 1-D nonlinear residual r = x^2 - 2 that counts its linearizations.
  class CountingBlock final : public ResidualBlock {
   public:
    int num_rows() const override { return 1; }
    std::span<const int> tangent_dims() const override { return dims_; }
    void evaluate_rows(ParameterPointers p, std::span<const int> rows, double* r,
                       double* J) const override {
      const double x = p[0][0];
      for (std::size_t k = 0; k < rows.size(); ++k) {
        r[k] = x * x - 2.0;
        if (J) J[k] = 2.0 * x;
      }
    }
    double accumulate(ParameterPointers p, Eigen::Ref<Eigen::MatrixXd> H,
                      Eigen::Ref<Eigen::VectorXd> b) const override {
      ++linearizations;
      return ResidualBlock::accumulate(p, H, b);
    }
    std::size_t memory_bytes() const override { return 0; }
    mutable int linearizations = 0;

   private:
    std::array<int, 1> dims_{1};
  };
  for (const int limit : {1, 3}) {
    Problem problem;
    const VariableId x = problem.add_euclidean(Eigen::VectorXd::Constant(1, 3.0));
    auto block = std::make_shared<CountingBlock>();
    problem.add_residual_block(block, {x});
    SolverOptions options;
    options.max_iterations = limit;
    options.function_tolerance = 0.0;
    options.gradient_tolerance = 0.0;
    options.parameter_tolerance = 0.0;
    const SolverSummary summary = solve(options, problem);
    EXPECT_EQ(summary.termination, TerminationType::kNoConvergence) << summary.message;
    EXPECT_EQ(summary.message,
              "maximum number of iterations reached (" + std::to_string(limit) + ")");
    EXPECT_EQ(summary.num_successful_steps, limit);
    // One linearization at the start and one per accepted iterate but the last.
    EXPECT_EQ(block->linearizations, limit);
    // The reported cost is the returned iterate's.
    const double v = problem.value(x)[0];
    EXPECT_DOUBLE_EQ(summary.final_cost, 0.5 * (v * v - 2.0) * (v * v - 2.0));
    EXPECT_LT(summary.final_cost, summary.initial_cost);
  }
}

TEST(SolveTest, ReusedFactorizationStepsKeepTheOptimum) {
  // factor_reuse_ratio 0: every accepted fresh step is followed by an attempt on its
  // factorization, so both kinds of step occur on the way to Rosenbrock's minimum.
  SolverOptions options;
  options.max_iterations = 200;
  options.function_tolerance = 1e-15;
  options.gradient_tolerance = 1e-14;
  options.factor_reuse_ratio = 0.0;
  options.anderson_memory = 0;  // the rules of slow tails, not those of an accelerated tail
  Problem problem;
  const VariableId x = problem.add_euclidean(Eigen::Vector2d(-1.2, 1.0));
  problem.add_residual_block(std::make_shared<RosenbrockBlock>(), {x});
  const SolverSummary summary = solve(options, problem);
  ASSERT_EQ(summary.termination, TerminationType::kConvergence) << summary.full_report();
  EXPECT_NEAR(problem.value(x)[0], 1.0, 1e-8);
  EXPECT_NEAR(problem.value(x)[1], 1.0, 1e-8);
  EXPECT_GT(summary.num_reused_factorizations, 0) << summary.full_report();
  EXPECT_GT(summary.num_refused_reuses, 0) << summary.full_report();
  int flagged = 0;
  for (const IterationSummary& row : summary.iterations) {
    if (!row.reused_factorization) continue;
    ++flagged;
    // A kept step lowered the cost and agreed with the current model to better than 1/2.
    EXPECT_TRUE(row.step_is_successful);
    EXPECT_GT(row.cost_change, 0.0);
    EXPECT_GT(row.relative_decrease, 0.5);
  }
  EXPECT_EQ(flagged, summary.num_reused_factorizations);
  EXPECT_NE(summary.full_report().find("(reused factorization)"), std::string::npos);
  EXPECT_NE(summary.to_json().find("\"reused_factorizations\":" +
                                   std::to_string(summary.num_reused_factorizations)),
            std::string::npos);

  // Off, and on a linear problem with the default threshold (gain ratio 1), nothing is reused.
  options.reuse_factorization = false;
  Problem again;
  const VariableId y = again.add_euclidean(Eigen::Vector2d(-1.2, 1.0));
  again.add_residual_block(std::make_shared<RosenbrockBlock>(), {y});
  const SolverSummary off = solve(options, again);
  EXPECT_EQ(off.num_reused_factorizations + off.num_refused_reuses, 0);
  EXPECT_NEAR(again.value(y)[0], 1.0, 1e-8);
  RandomLinear lin = make_random_linear(20, 9);
  const SolverSummary linear = solve(SolverOptions{}, lin.problem);
  EXPECT_EQ(linear.num_reused_factorizations + linear.num_refused_reuses, 0);
}

TEST(SolveTest, TrustRegionGrowsByAtMostTheSetFactor) {
  // On a linear problem the gain ratio is 1, so the radius grows by exactly the cap.
  for (const double growth : {3.0, 10.0}) {
    RandomLinear lin = make_random_linear(15, 4);
    SolverOptions options;
    options.lm_start = LmStart::kTrustRegion;  // the growth from the initial radius
    options.max_trust_region_growth = growth;
    options.function_tolerance = 0.0;
    options.max_iterations = 2;
    const SolverSummary summary = solve(options, lin.problem);
    ASSERT_GE(summary.iterations.size(), 2u) << summary.full_report();
    EXPECT_DOUBLE_EQ(summary.iterations[1].trust_region_radius,
                     options.initial_trust_region_radius * growth);
  }
}

TEST(SolverOptionsTest, ValidateNamesTheBadSetting) {
  std::string error;
  SolverOptions options;
  EXPECT_TRUE(options.validate(&error));
  // One bad setting at a time: validate() fails with exactly this message.
  const auto expect_invalid = [](void (*change)(SolverOptions&), const std::string& message) {
    SolverOptions bad;
    change(bad);
    std::string why;
    EXPECT_FALSE(bad.validate(&why)) << message;
    EXPECT_EQ(why, message);
  };
  expect_invalid([](SolverOptions& o) { o.num_threads = 0; }, "num_threads must be >= 1, got 0");
  expect_invalid([](SolverOptions& o) { o.function_tolerance = -1.0; },
                 "function_tolerance must be finite and >= 0, got -1.000000");
  expect_invalid([](SolverOptions& o) { o.max_trust_region_growth = 0.5; },
                 "max_trust_region_growth must be 0 (automatic) or finite and >= 1, got 0.500000");
  expect_invalid([](SolverOptions& o) { o.factor_reuse_ratio = -1.0; },
                 "factor_reuse_ratio must be finite and >= 0, got -1.000000");
  expect_invalid([](SolverOptions& o) { o.anderson_memory = -1; },
                 "anderson_memory must be in [0, 64], got -1");
  expect_invalid([](SolverOptions& o) { o.anderson_memory = 65; },
                 "anderson_memory must be in [0, 64], got 65");
  expect_invalid([](SolverOptions& o) { o.gauss_newton_phase_min_gain = 1.5; },
                 "gauss_newton_phase_min_gain must be in [0, 1], got 1.500000");
  expect_invalid([](SolverOptions& o) { o.gauss_newton_phase_radius = 1e20; },
                 "gauss_newton_phase_radius must be > 0 and <= max_trust_region_radius");
  options.initial_trust_region_radius = 0.0;
  EXPECT_FALSE(options.validate(&error));
  // solve() reports invalid options through the summary instead of throwing.
  Problem problem;
  problem.add_euclidean(Eigen::VectorXd::Zero(1));
  const SolverSummary summary = solve(options, problem);
  EXPECT_EQ(summary.termination, TerminationType::kFailure);
  EXPECT_NE(summary.message.find("invalid options: initial_trust_region_radius"),
            std::string::npos);
}

TEST(SolverOptionsTest, MethodAndOrderingNamesRoundTrip) {
  for (Method method : {Method::kLevenbergMarquardt, Method::kGaussNewton}) {
    EXPECT_EQ(parse_method(to_string(method)), method) << to_string(method);
  }
  EXPECT_STREQ(to_string(Method::kLevenbergMarquardt), "lm");
  EXPECT_STREQ(to_string(Method::kGaussNewton), "gn");
  for (Ordering ordering : {Ordering::kAuto, Ordering::kAmd, Ordering::kMetis}) {
    EXPECT_EQ(parse_ordering(to_string(ordering)), ordering) << to_string(ordering);
  }
  EXPECT_STREQ(to_string(Ordering::kMetis), "metis");
  for (LmStart start : {LmStart::kAuto, LmStart::kGaussNewton, LmStart::kTrustRegion}) {
    EXPECT_EQ(parse_lm_start(to_string(start)), start) << to_string(start);
  }
  EXPECT_STREQ(to_string(LmStart::kGaussNewton), "gauss_newton");
  EXPECT_EQ(test::error_of([] { parse_lm_start("gn"); }),
            "unknown LM start 'gn' (valid: auto, gauss_newton, trust_region)");
  EXPECT_EQ(test::error_of([] { parse_method("newton"); }),
            "unknown method 'newton' (valid: lm, gn)");
  EXPECT_EQ(test::error_of([] { parse_method("LM"); }), "unknown method 'LM' (valid: lm, gn)");
  EXPECT_EQ(test::error_of([] { parse_ordering("colamd"); }),
            "unknown ordering 'colamd' (valid: auto, amd, metis)");
  EXPECT_EQ(test::error_of([] { parse_ordering(""); }),
            "unknown ordering '' (valid: auto, amd, metis)");
}

TEST(ProblemTest, RejectsMismatchedBlocksWithClearMessages) {
  Problem problem;
  const VariableId a = problem.add_euclidean(Eigen::Vector3d::Zero());
  const VariableId b = problem.add_se3(Eigen::Isometry3d::Identity());
  auto rosen = std::make_shared<RosenbrockBlock>();
  try {
    problem.add_residual_block(rosen, {a});
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(),
                 "Problem::add_residual_block (block 0): variable 0 has tangent size 3 but the "
                 "block expects 2");
  }
  try {
    problem.add_residual_block(rosen, {a, b});
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(),
                 "Problem::add_residual_block (block 0): the block expects 1 variables, got 2");
  }
  try {
    problem.add_residual_block(rosen, {VariableId{7}});
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "Problem: variable id 7 does not exist (2 variables)");
  }
  const double bad_quaternion[7] = {0, 0, 0, 0, 0, 0, 0};
  EXPECT_THROW(problem.add_variable(se3_manifold(), bad_quaternion), Error);
  const double nan_value[3] = {0, std::nan(""), 0};
  EXPECT_THROW(problem.add_variable(euclidean_manifold(3), nan_value), Error);
  EXPECT_THROW(problem.set_all_values(std::vector<double>(3, 0.0)), Error);
}

TEST(ProblemTest, NonRigidPosesAreRefusedNamingTheVariable) {
  Problem problem;
  problem.add_euclidean(Eigen::Vector2d::Zero());
  Eigen::Isometry3d scaled = Eigen::Isometry3d::Identity();
  scaled.linear() *= 2.0;
  EXPECT_EQ(test::error_of([&] { problem.add_se3(scaled); }),
            "Problem::add_se3 (variable 1): T_world_body has a rotation block that is not "
            "orthonormal (scaled or sheared: |R^T R - I| > 1e-6)");
  Eigen::Isometry3d reflected = Eigen::Isometry3d::Identity();
  reflected.linear()(2, 2) = -1.0;
  EXPECT_EQ(test::error_of([&] { problem.add_se3(reflected); }),
            "Problem::add_se3 (variable 1): T_world_body has a reflection, not a rotation "
            "(det R < 0)");
  Eigen::Isometry3d not_finite = Eigen::Isometry3d::Identity();
  not_finite.translation().x() = std::nan("");
  EXPECT_EQ(test::error_of([&] { problem.add_se3(not_finite); }),
            "Problem::add_se3 (variable 1): T_world_body is not finite");
  Eigen::Isometry2d sheared = Eigen::Isometry2d::Identity();
  sheared.linear()(0, 1) = 0.5;
  EXPECT_EQ(test::error_of([&] { problem.add_se2(sheared); }),
            "Problem::add_se2 (variable 1): T_world_body has a rotation block that is not "
            "orthonormal (scaled or sheared: |R^T R - I| > 1e-6)");
  EXPECT_EQ(problem.num_variables(), 1);  // nothing was stored
  // Rounding of a product of rotations is no reason to refuse.
  Eigen::Isometry3d chained = Eigen::Isometry3d::Identity();
  for (int k = 0; k < 1000; ++k)
    chained = chained * Eigen::AngleAxisd(0.1, Eigen::Vector3d(1, 2, 3).normalized());
  EXPECT_EQ(problem.add_se3(chained).index, 1);
}

TEST(SummaryTest, ReportsContainTheTableAndTheBreakdown) {
  RandomLinear lin = make_random_linear(10, 5);
  const SolverSummary summary = solve(SolverOptions{}, lin.problem);
  const std::string full = summary.full_report();
  EXPECT_NE(full.find("iter      cost      cost_change  |gradient|"), std::string::npos);
  EXPECT_NE(full.find("numeric factorization"), std::string::npos);
  EXPECT_NE(full.find("Termination: CONVERGENCE"), std::string::npos);
  EXPECT_EQ(summary.iterations.size(), static_cast<std::size_t>(summary.num_iterations) + 1);
  const std::string json = summary.to_json();
  for (const char* key : {"\"initial_cost\"", "\"final_cost\"", "\"iterations\"", "\"termination\"",
                          "\"time_s\"", "\"time_breakdown\""}) {
    EXPECT_NE(json.find(key), std::string::npos) << key;
  }
}

// The report's small print: a failed solve shows no costs it never had, invalid options still
// name the method, stopping reasons show their values, every iteration is counted as accepted
// or rejected, and no "nan" reaches the table.
TEST(SummaryTest, ReportsStayTruthfulAtTheEdges) {
  RandomLinear invalid = make_random_linear(4, 2);
  SolverOptions bad;
  bad.max_iterations = -1;
  const SolverSummary refused = solve(bad, invalid.problem);
  EXPECT_EQ(refused.method, "levenberg_marquardt");
  EXPECT_EQ(refused.brief_report().find("cost 0"), std::string::npos) << refused.brief_report();
  EXPECT_NE(refused.brief_report().find("FAILURE (invalid options: max_iterations must be >= 0"),
            std::string::npos)
      << refused.brief_report();

  // Rosenbrock ends on a tiny gradient: the message shows it, not "0.000000".
  Problem rosenbrock;
  const VariableId x = rosenbrock.add_euclidean(Eigen::Vector2d(-1.2, 1.0));
  rosenbrock.add_residual_block(std::make_shared<RosenbrockBlock>(), {x});
  SolverOptions options;
  options.max_iterations = 100;
  options.function_tolerance = 0.0;
  options.gradient_tolerance = 1e-9;
  options.parameter_tolerance = 0.0;
  const SolverSummary converged = solve(options, rosenbrock);
  EXPECT_EQ(converged.termination, TerminationType::kConvergence) << converged.message;
  EXPECT_EQ(converged.message.find("0.000000"), std::string::npos) << converged.message;
  EXPECT_NE(converged.message.find("e-"), std::string::npos) << converged.message;
  EXPECT_EQ(converged.num_iterations,
            converged.num_successful_steps + converged.num_unsuccessful_steps);

  // Ended by the parameter tolerance (the last step computed is not taken), by the iteration
  // limit after rejections, and by Gauss-Newton: every iteration is counted once.
  for (const Method method : {Method::kLevenbergMarquardt, Method::kGaussNewton}) {
    for (const double parameter_tolerance : {1e-3, 1e-8}) {
      for (const int limit : {2, 5, 100}) {
        Problem problem;
        const VariableId y = problem.add_euclidean(Eigen::Vector2d(-1.2, 1.0));
        problem.add_residual_block(std::make_shared<RosenbrockBlock>(), {y});
        SolverOptions o;
        o.method = method;
        o.parameter_tolerance = parameter_tolerance;
        o.max_iterations = limit;
        const SolverSummary s = solve(o, problem);
        EXPECT_EQ(s.num_iterations, s.num_successful_steps + s.num_unsuccessful_steps)
            << s.full_report();
        EXPECT_EQ(s.full_report().find("nan"), std::string::npos) << s.full_report();
      }
    }
  }

  // r = log(x) from x = 10: the first undamped-enough step lands at x < 0, where the cost is
  // NaN; the step is rejected and the table shows "-" where the gain ratio is no number.
  class LogBlock final : public ResidualBlock {
   public:
    int num_rows() const override { return 1; }
    std::span<const int> tangent_dims() const override { return dims_; }
    void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* r,
                       double* J) const override {
      for (std::size_t k = 0; k < rows.size(); ++k) {
        r[k] = std::log(params[0][0]);
        if (J) J[k] = 1.0 / params[0][0];
      }
    }
    std::size_t memory_bytes() const override { return 0; }

   private:
    std::array<int, 1> dims_{1};
  };
  Problem log_problem;
  const VariableId z = log_problem.add_euclidean(Eigen::VectorXd::Constant(1, 10.0));
  log_problem.add_residual_block(std::make_shared<LogBlock>(), {z});
  SolverOptions wide;
  wide.initial_trust_region_radius = 1e16;
  const SolverSummary nan_step = solve(wide, log_problem);
  EXPECT_GE(nan_step.num_unsuccessful_steps, 1) << nan_step.full_report();
  EXPECT_EQ(nan_step.iteration_table().find("nan"), std::string::npos) << nan_step.full_report();
  EXPECT_NEAR(log_problem.value(z)[0], 1.0, 1e-6);
}

/// Serves the blocks of its own problem (same variables as the solved one) through a
/// BlockLinearizer, in runs of `run` blocks; `spoil` (if set) edits the records first.
class LinearizerSource final : public BlockSource {
 public:
  LinearizerSource(Problem blocks, std::size_t run)
      : blocks_(std::move(blocks)), linearizer_(blocks_, 2, 5), run_(run) {}
  std::size_t num_blocks() const override { return blocks_.blocks().size(); }
  std::span<const VariableId> variables(std::size_t k) const override {
    return blocks_.blocks()[k].variables;
  }
  void linearize(std::span<const double> values, const BlockRecordSink& sink) override {
    std::vector<double> records;
    linearizer_.linearize(values, [&](std::size_t, std::span<const double> run) {
      records.insert(records.end(), run.begin(), run.end());
    });
    if (spoil) spoil(&records);
    std::size_t at = 0;
    for (std::size_t k = 0; k < num_blocks(); k += run_) {
      std::size_t size = 0;
      for (std::size_t q = k; q < std::min(k + run_, num_blocks()); ++q)
        size += linearization_record_size(blocks_.blocks()[q].block->tangent_dim());
      sink(k + first_shift, std::span<const double>(records).subspan(at, size));
      at += size;
    }
  }
  void costs(std::span<const double> values, const BlockRecordSink& sink) override {
    linearizer_.costs(values, sink);
  }
  std::function<void(std::vector<double>*)> spoil;  ///< edits the records before they are sent
  std::size_t first_shift = 0;                      ///< added to each run's first index

 private:
  Problem blocks_;
  BlockLinearizer linearizer_;
  std::size_t run_;
};

/// The random linear problem with a Rosenbrock variable and Cauchy losses on every third block;
/// `own` of its blocks stay in the returned problem, the others go to a LinearizerSource, which
/// is returned too (when own < all).
struct SplitProblem {
  Problem problem;
  std::shared_ptr<LinearizerSource> source;
};

SplitProblem split_problem(std::size_t own) {
  RandomLinear lin = make_random_linear(120, 5);
  const VariableId r = lin.problem.add_euclidean(Eigen::Vector2d(-1.2, 1.0));
  lin.problem.add_residual_block(std::make_shared<RosenbrockBlock>(), {r});
  SplitProblem out;
  Problem rest;
  for (Problem* p : {&out.problem, &rest}) {
    for (int v = 0; v < lin.problem.num_variables(); ++v) {
      const std::span<const double> value = lin.problem.value(VariableId{v});
      p->add_euclidean(
          Eigen::Map<const Eigen::VectorXd>(value.data(), static_cast<Eigen::Index>(value.size())));
    }
    p->set_constant(VariableId{1});
  }
  const auto loss = std::make_shared<CauchyLoss>(0.5);
  const auto blocks = lin.problem.blocks();
  for (std::size_t k = 0; k < blocks.size(); ++k) {
    Problem& to = k < own ? out.problem : rest;
    to.add_residual_block(blocks[k].block, blocks[k].variables, k % 3 == 0 ? loss : nullptr);
  }
  if (own < blocks.size()) {
    out.source = std::make_shared<LinearizerSource>(std::move(rest), 7);
    out.problem.set_block_source(out.source);
  }
  return out;
}

TEST(BlockSourceTest, SolvesBitForBitAsTheSameBlocksAddedAfterTheOwnOnes) {
  SolverOptions options;
  options.max_iterations = 40;
  options.num_threads = 2;
  SplitProblem whole = split_problem(std::numeric_limits<std::size_t>::max());
  const double start_cost = evaluate_cost(whole.problem);
  const ProblemEvaluation start = evaluate_problem(whole.problem);
  const SolverSummary reference = solve(options, whole.problem);
  ASSERT_TRUE(reference.is_solution_usable()) << reference.message;
  ASSERT_GT(reference.iterations.size(), 3u);
  for (const std::size_t own : {std::size_t{0}, std::size_t{150}}) {
    SplitProblem split = split_problem(own);
    EXPECT_NEAR(evaluate_cost(split.problem), start_cost, 1e-12 * start_cost);
    const ProblemEvaluation a = evaluate_problem(split.problem);
    EXPECT_NEAR(a.cost, start.cost, 1e-12 * start.cost);
    EXPECT_NEAR((a.gradient - start.gradient).norm(), 0.0, 1e-12 * start.gradient.norm());
    const SolverSummary summary = solve(options, split.problem);
    EXPECT_EQ(summary.num_residual_blocks, reference.num_residual_blocks);
    ASSERT_EQ(summary.iterations.size(), reference.iterations.size()) << own;
    EXPECT_EQ(summary.final_cost, reference.final_cost) << own;
    const auto values = split.problem.all_values();
    const auto expected = whole.problem.all_values();
    for (std::size_t i = 0; i < values.size(); ++i)
      ASSERT_EQ(values[i], expected[i]) << "value " << i << ", " << own << " own blocks";
  }
}

TEST(BlockSourceTest, AMisbehavingSourceFailsTheSolveNamingWhatWentWrong) {
  SolverOptions options;
  options.max_iterations = 5;
  {  // A record that is not finite fails the solve naming the block, as an own block's would.
    SplitProblem split = split_problem(150);
    split.source->spoil = [](std::vector<double>* records) { (*records)[100] = NAN; };
    const SolverSummary summary = solve(options, split.problem);
    EXPECT_EQ(summary.termination, TerminationType::kFailure);
    EXPECT_THAT(summary.message, testing::HasSubstr("is not finite"));
    EXPECT_THAT(summary.message, testing::HasSubstr("of the block source"));
  }
  {  // Runs out of order.
    SplitProblem split = split_problem(150);
    split.source->first_shift = 1;
    EXPECT_THAT([&] { solve(options, split.problem); },
                ThrowsMessage<Error>(testing::HasSubstr(
                    "block source: records of block 1 arrived where block 0 was expected")));
  }
  {  // Only the whole sparse system takes a source.
    SplitProblem split = split_problem(150);
    options.linear_solver = LinearSolver::kSchur;
    const SolverSummary summary = solve(options, split.problem);
    EXPECT_EQ(summary.termination, TerminationType::kFailure);
    EXPECT_EQ(summary.message,
              "linear solver schur: a problem with a block source is solved as the whole sparse "
              "system (use cholesky or auto)");
  }
  {  // A block over a variable the problem does not have.
    Problem problem;
    problem.add_euclidean(Eigen::Vector2d::Zero());
    Problem other;
    const VariableId a = other.add_euclidean(Eigen::Vector2d::Zero());
    const VariableId b = other.add_euclidean(Eigen::Vector2d::Zero());
    other.add_residual_block(
        std::make_shared<LinearBlock>(std::vector<Eigen::MatrixXd>{Eigen::MatrixXd::Identity(2, 2),
                                                                   Eigen::MatrixXd::Identity(2, 2)},
                                      Eigen::Vector2d::Ones()),
        {a, b});
    EXPECT_THAT(
        [&] { problem.set_block_source(std::make_shared<LinearizerSource>(std::move(other), 1)); },
        ThrowsMessage<Error>(testing::HasSubstr(
            "Problem::set_block_source (source block 0): variable 1 is not in the "
            "problem (1 variables)")));
  }
}

}  // namespace
}  // namespace carat
