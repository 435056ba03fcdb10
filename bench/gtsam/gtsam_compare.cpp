// Side-by-side: GTSAM and carat solve the same g2o pose graphs in the same run, interleaved,
// 1 thread by default (GTSAM built without TBB; see docs/benchmarks.md for the build lines).
// --threads N gives carat N linearization threads and, when GTSAM was built with TBB, limits
// TBB to N threads (tbb::global_control); a GTSAM without TBB runs on one thread regardless.
//
// Both start from the file's vertices and hold the first vertex: carat as a constant variable,
// GTSAM with a PriorFactor of sigma 1e-6 (as its Pose3SLAMExample_g2o / Pose2SLAMExample_g2o).
// The factors come from carat's parse of the file, so both read the same numbers. GTSAM runs:
//   gtsam_default  BetweenFactor<Pose3/Pose2> (error Log(Z^-1 T_a^-1 T_b), GTSAM's default
//                  approximate Jacobian of that Log), the g2o information as its Gaussian
//                  noise model, LevenbergMarquardtParams() (lambda 1e-5, COLAMD, multifrontal
//                  Cholesky, relative and absolute error tolerance 1e-5);
//   gtsam_exact    the same error with its exact Jacobian (GTSAM's own Local() Jacobian, the
//                  GTSAM_SLOW_BUT_CORRECT_BETWEENFACTOR variant written as a factor here);
//   gtsam_metis    gtsam_exact with METIS ordering;
//   gtsam_same_cost carat's residual as a GTSAM factor with carat's analytic Jacobian, the
//                  identical cost function: 3-D Ceres's pose_graph_3d error, 2-D carat's
//                  whitened Log(Z^-1 T_a^-1 T_b) (GTSAM's Pose2 default chart is not Log: its
//                  BetweenFactor<Pose2> minimizes [x, y, theta] of Z^-1 T_a^-1 T_b instead).
// carat runs solve() with its defaults (max 200 iterations), from a problem built in-process.
// Times are each solver's optimize call alone (building the graph and reading the file not
// included: "in-process"); the best of --repeat runs is reported beside every run's.
//
// One evaluator scores every output: carat's cost (1/2 the sum of squared whitened residuals
// of carat's blocks, "cost_carat") and GTSAM's error of the default BetweenFactor graph without
// the prior ("cost_gtsam", also 1/2 the sum). The two cost functions agree to first order.
//
// --bal: bundle adjustment instead, on the synthetic BAL problems of bench/ceres/bal_compare.cpp
// (Snavely model; generated in-process, seed 7). GTSAM gets its SfM setup: one
// GeneralSFMFactor<PinholeCamera<Cal3Bundler>, Point3> per observation with a unit noise model,
// the BAL camera turned into GTSAM's (axes y and z flipped, the observation's y negated: the same
// residuals up to sign), no prior (the gauge is left to LM's damping, as carat leaves it),
// LevenbergMarquardtParams() with COLAMD ("gtsam_default") and with METIS ("gtsam_metis").
// carat runs solve() with its defaults on add_bal_problem() (points eliminated, Schur
// complement). One evaluator: carat's bal_cost() of every output (1/2 the sum of squares, px^2).
//
// Usage: gtsam_compare [--repeat N] [--threads N] FILE.g2o...   (one JSON object per file)
//        gtsam_compare [--repeat N] [--threads N] --bal [--quick]  (one JSON object per problem)
#include <gtsam/geometry/Cal3Bundler.h>
#include <gtsam/geometry/PinholeCamera.h>
#include <gtsam/geometry/Pose2.h>
#include <gtsam/geometry/Pose3.h>
#include <gtsam/inference/Symbol.h>
#include <gtsam/nonlinear/LevenbergMarquardtOptimizer.h>
#include <gtsam/nonlinear/NonlinearFactorGraph.h>
#include <gtsam/nonlinear/PriorFactor.h>
#include <gtsam/nonlinear/Values.h>
#include <gtsam/slam/BetweenFactor.h>
#include <gtsam/slam/GeneralSFMFactor.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <variant>
#include <vector>

#include "carat/base/blas_kernels.hpp"
#include "carat/base/stopwatch.hpp"
#ifdef GTSAM_USE_TBB
#include <tbb/global_control.h>
#endif
#include "../synthetic_bal_cases.hpp"
#include "carat/residuals/bal_problem.hpp"
#include "carat/residuals/io/g2o_io.hpp"
#include "carat/residuals/pose_graph.hpp"
#include "carat/residuals/pose_graph_se2.hpp"
#include "carat/residuals/relative_pose_block.hpp"
#include "carat/residuals/relative_pose_se2_block.hpp"
#include "carat/sim/bal_scene.hpp"
#include "carat/solver/evaluate.hpp"
#include "carat/solver/se2.hpp"
#include "carat/solver/se3.hpp"
#include "carat/solver/so3.hpp"
#include "carat/solver/solve.hpp"

namespace {

int g_threads = 1;  ///< --threads: carat's linearization threads (and TBB's, when GTSAM has it)

/// GTSAM's between error Log(Z^-1 h(x)) with the exact Jacobian of Local (what
/// GTSAM_SLOW_BUT_CORRECT_BETWEENFACTOR compiles into BetweenFactor).
template <typename T>
class ExactBetweenFactor final : public gtsam::NoiseModelFactorN<T, T> {
 public:
  ExactBetweenFactor(gtsam::Key a, gtsam::Key b, const T& measured,
                     const gtsam::SharedNoiseModel& noise)
      : gtsam::NoiseModelFactorN<T, T>(noise, a, b), measured_(measured) {}

  gtsam::Vector evaluateError(const T& p1, const T& p2, gtsam::OptionalMatrixType H1,
                              gtsam::OptionalMatrixType H2) const override {
    const T hx = gtsam::traits<T>::Between(p1, p2, H1, H2);
    typename gtsam::traits<T>::ChartJacobian::Jacobian H_local;
    const gtsam::Vector error =
        gtsam::traits<T>::Local(measured_, hx, {}, (H1 || H2) ? &H_local : nullptr);
    if (H1) *H1 = H_local * (*H1);
    if (H2) *H2 = H_local * (*H2);
    return error;
  }

 private:
  T measured_;
};

/// carat's RelativePoseBlock (whitened Ceres pose_graph_3d error, Jacobians on the right
/// tangents [omega, v], which are GTSAM's Pose3 tangents under its Expmap retraction) as a GTSAM
/// factor with a unit noise model: the identical cost function.
class CaratRelativePoseFactor final : public gtsam::NoiseModelFactorN<gtsam::Pose3, gtsam::Pose3> {
 public:
  CaratRelativePoseFactor(gtsam::Key a, gtsam::Key b, const carat::PoseGraph::Edge& edge)
      : gtsam::NoiseModelFactorN<gtsam::Pose3, gtsam::Pose3>(gtsam::noiseModel::Unit::Create(6), a,
                                                             b),
        block_(edge.T_from_to, edge.information) {}

  gtsam::Vector evaluateError(const gtsam::Pose3& p1, const gtsam::Pose3& p2,
                              gtsam::OptionalMatrixType H1,
                              gtsam::OptionalMatrixType H2) const override {
    double a[7], b[7];
    carat::se3::to_storage(Eigen::Isometry3d(p1.matrix()), a);
    carat::se3::to_storage(Eigen::Isometry3d(p2.matrix()), b);
    Eigen::Matrix<double, 6, 1> r;
    Eigen::Matrix<double, 6, 12> J;
    block_.evaluate(a, b, &r, (H1 || H2) ? &J : nullptr);
    if (H1) *H1 = J.leftCols<6>();
    if (H2) *H2 = J.rightCols<6>();
    return r;
  }

 private:
  carat::RelativePoseBlock block_;
};

/// carat's RelativePoseSE2Block (whitened Log(Z^-1 T_a^-1 T_b), tangents [omega, vx, vy]) as a
/// GTSAM factor: GTSAM's Pose2 retraction T Pose2(vx, vy, omega) agrees with carat's T Exp(xi) to
/// first order, so the Jacobian is carat's with its columns in GTSAM's order [vx, vy, omega].
class CaratRelativePoseSE2Factor final
    : public gtsam::NoiseModelFactorN<gtsam::Pose2, gtsam::Pose2> {
 public:
  CaratRelativePoseSE2Factor(gtsam::Key a, gtsam::Key b, const carat::PoseGraphSE2::Edge& edge)
      : gtsam::NoiseModelFactorN<gtsam::Pose2, gtsam::Pose2>(gtsam::noiseModel::Unit::Create(3), a,
                                                             b),
        block_(edge.T_from_to, edge.information) {}

  gtsam::Vector evaluateError(const gtsam::Pose2& p1, const gtsam::Pose2& p2,
                              gtsam::OptionalMatrixType H1,
                              gtsam::OptionalMatrixType H2) const override {
    const double a[3] = {p1.x(), p1.y(), p1.theta()};
    const double b[3] = {p2.x(), p2.y(), p2.theta()};
    Eigen::Vector3d r;
    Eigen::Matrix<double, 3, 6> J;
    block_.evaluate(a, b, &r, (H1 || H2) ? &J : nullptr);
    const auto reorder = [](const Eigen::Matrix3d& carat_order) {
      Eigen::Matrix3d out;
      out << carat_order.col(1), carat_order.col(2), carat_order.col(0);
      return out;
    };
    if (H1) *H1 = reorder(J.leftCols<3>());
    if (H2) *H2 = reorder(J.rightCols<3>());
    return r;
  }

 private:
  carat::RelativePoseSE2Block block_;
};

gtsam::Pose3 to_gtsam(const Eigen::Isometry3d& T) { return gtsam::Pose3(T.matrix()); }
gtsam::Pose2 to_gtsam(const Eigen::Isometry2d& T) {
  return gtsam::Pose2(T.translation().x(), T.translation().y(),
                      std::atan2(T.linear()(1, 0), T.linear()(0, 0)));
}
Eigen::Isometry3d to_carat(const gtsam::Pose3& T) { return Eigen::Isometry3d(T.matrix()); }
Eigen::Isometry2d to_carat(const gtsam::Pose2& T) {
  Eigen::Isometry2d out = Eigen::Isometry2d::Identity();
  out.linear() = T.rotation().matrix();
  out.translation() = T.translation();
  return out;
}

/// The g2o information (translation first) in GTSAM's Pose3 tangent order [omega, v].
Eigen::Matrix<double, 6, 6> gtsam_information(const carat::se3::Matrix6d& information) {
  Eigen::Matrix<double, 6, 6> P = Eigen::Matrix<double, 6, 6>::Zero();
  P.block<3, 3>(0, 3).setIdentity();
  P.block<3, 3>(3, 0).setIdentity();
  return P * information * P.transpose();
}
/// The g2o information (x, y, theta), already GTSAM's Pose2 tangent order.
Eigen::Matrix3d gtsam_information(const Eigen::Matrix3d& information) { return information; }

/// The factors of one variant of the graph (no prior).
enum class Variant { kDefault, kExact, kSameCost };

template <typename Graph>
gtsam::NonlinearFactorGraph make_factors(const Graph& graph, Variant variant) {
  using Pose = decltype(to_gtsam(graph.vertices.front().T_world_vertex));
  gtsam::NonlinearFactorGraph factors;
  for (const auto& edge : graph.edges) {
    const gtsam::Key a = static_cast<gtsam::Key>(graph.index_of(edge.from));
    const gtsam::Key b = static_cast<gtsam::Key>(graph.index_of(edge.to));
    if (variant == Variant::kSameCost) {
      if constexpr (std::is_same_v<Pose, gtsam::Pose3>) {
        factors.emplace_shared<CaratRelativePoseFactor>(a, b, edge);
      } else {
        factors.emplace_shared<CaratRelativePoseSE2Factor>(a, b, edge);
      }
      continue;
    }
    const auto noise =
        gtsam::noiseModel::Gaussian::Information(gtsam_information(edge.information));
    const Pose measured = to_gtsam(edge.T_from_to);
    if (variant == Variant::kDefault) {
      factors.emplace_shared<gtsam::BetweenFactor<Pose>>(a, b, measured, noise);
    } else {
      factors.emplace_shared<ExactBetweenFactor<Pose>>(a, b, measured, noise);
    }
  }
  return factors;
}

template <typename Graph>
gtsam::Values initial_values(const Graph& graph) {
  gtsam::Values values;
  for (std::size_t i = 0; i < graph.vertices.size(); ++i) {
    values.insert(static_cast<gtsam::Key>(i), to_gtsam(graph.vertices[i].T_world_vertex));
  }
  return values;
}

/// carat's cost of the poses `values` (keys = vertex indices).
template <typename Graph>
double carat_cost(Graph graph, const gtsam::Values& values) {
  using Pose = decltype(to_gtsam(graph.vertices.front().T_world_vertex));
  for (std::size_t i = 0; i < graph.vertices.size(); ++i) {
    graph.vertices[i].T_world_vertex = to_carat(values.at<Pose>(static_cast<gtsam::Key>(i)));
  }
  return carat::evaluate_cost(carat::build_pose_graph_problem(graph).problem);
}

template <typename Graph>
nlohmann::json run_gtsam(const Graph& graph, Variant variant, gtsam::Ordering::OrderingType order,
                         const gtsam::NonlinearFactorGraph& evaluator) {
  using Pose = decltype(to_gtsam(graph.vertices.front().T_world_vertex));
  gtsam::NonlinearFactorGraph factors = make_factors(graph, variant);
  const auto sigmas = gtsam::Vector::Constant(gtsam::traits<Pose>::dimension, 1e-6);
  factors.addPrior(gtsam::Key{0}, to_gtsam(graph.vertices.front().T_world_vertex),
                   gtsam::noiseModel::Diagonal::Sigmas(sigmas));
  const gtsam::Values initial = initial_values(graph);
  gtsam::LevenbergMarquardtParams params;  // GTSAM's defaults
  params.orderingType = order;
  params.maxIterations = 200;
  const carat::Stopwatch clock;
  gtsam::LevenbergMarquardtOptimizer optimizer(factors, initial, params);
  const gtsam::Values result = optimizer.optimize();
  const double seconds = clock.elapsed_s();
  return {{"time_s", seconds},
          {"iterations", optimizer.iterations()},
          {"own_final_error", optimizer.error()},
          {"cost_carat", carat_cost(graph, result)},
          {"cost_gtsam", evaluator.error(result)}};
}

template <typename Graph>
nlohmann::json run_carat(const Graph& graph, const gtsam::NonlinearFactorGraph& evaluator) {
  using Pose = decltype(to_gtsam(graph.vertices.front().T_world_vertex));
  carat::PoseGraphProblem built = carat::build_pose_graph_problem(graph);
  carat::SolverOptions options;
  options.max_iterations = 200;
  options.num_threads = g_threads;
  const carat::Stopwatch clock;
  const carat::SolverSummary summary = carat::solve(options, built.problem);
  const double seconds = clock.elapsed_s();
  Graph solved = graph;
  carat::update_vertices(built, &solved);
  gtsam::Values values;
  for (std::size_t i = 0; i < solved.vertices.size(); ++i) {
    values.insert(static_cast<gtsam::Key>(i), to_gtsam(solved.vertices[i].T_world_vertex));
  }
  int factorizations = 0;
  for (const auto& row : summary.iterations) {
    if (row.iteration > 0 && !row.reused_factorization) ++factorizations;
  }
  return {{"time_s", seconds},
          {"iterations", summary.num_iterations},
          {"factorizations", factorizations},
          {"termination", carat::to_string(summary.termination)},
          {"cost_carat", summary.final_cost},
          {"cost_gtsam", evaluator.error(values)}};
}

template <typename Graph>
nlohmann::json compare(const Graph& graph, int repeat) {
  const gtsam::NonlinearFactorGraph evaluator = make_factors(graph, Variant::kDefault);
  struct Runner {
    const char* name;
    std::function<nlohmann::json()> run;
  };
  std::vector<Runner> runners = {
      {"carat", [&] { return run_carat(graph, evaluator); }},
      {"gtsam_default",
       [&] { return run_gtsam(graph, Variant::kDefault, gtsam::Ordering::COLAMD, evaluator); }},
      {"gtsam_exact",
       [&] { return run_gtsam(graph, Variant::kExact, gtsam::Ordering::COLAMD, evaluator); }},
      {"gtsam_metis",
       [&] { return run_gtsam(graph, Variant::kExact, gtsam::Ordering::METIS, evaluator); }}};
  runners.push_back(
      {"gtsam_same_cost",
       [&] { return run_gtsam(graph, Variant::kSameCost, gtsam::Ordering::COLAMD, evaluator); }});
  nlohmann::json out;
  for (int r = 0; r < repeat; ++r) {  // interleaved: one run of each per round
    for (const Runner& runner : runners) {
      nlohmann::json run = runner.run();
      nlohmann::json& slot = out[runner.name];
      slot["times_s"].push_back(run["time_s"]);
      const double best =
          slot.contains("best_time_s") ? slot["best_time_s"].template get<double>() : 1e300;
      slot["best_time_s"] = std::min(best, run["time_s"].template get<double>());
      run.erase("time_s");
      for (auto& [key, value] : run.items()) slot[key] = value;
    }
  }
  const double carat_time = out["carat"]["best_time_s"].template get<double>();
  for (auto& [name, slot] : out.items()) {
    if (name != "carat")
      slot["carat_time_ratio"] = carat_time / slot["best_time_s"].template get<double>();
  }
  return out;
}

// ---- Bundle adjustment ----

using SfmCamera = gtsam::PinholeCamera<gtsam::Cal3Bundler>;
const Eigen::Matrix3d kFlip = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();

/// A BAL camera (P = R X + t, image = -f d(r) P.xy / P.z) as GTSAM's: camera axes y and z
/// flipped, so that GTSAM's image (+f d(r) P'.xy / P'.z) is BAL's with y negated.
SfmCamera to_gtsam(const carat::BalCamera& c) {
  const Eigen::Matrix3d R = carat::so3::exp(c.head<3>()).toRotationMatrix();
  const Eigen::Matrix3d R_camera_world = kFlip * R;  // GTSAM camera frame from world
  const Eigen::Vector3d t_camera = kFlip * c.segment<3>(3);
  const gtsam::Rot3 R_world_camera(R_camera_world.transpose());
  const gtsam::Point3 t_world_camera = -(R_camera_world.transpose() * t_camera);
  return SfmCamera(gtsam::Pose3(R_world_camera, t_world_camera),
                   gtsam::Cal3Bundler(c[6], c[7], c[8]));
}

/// The inverse of to_gtsam(SfmCamera).
carat::BalCamera to_bal(const SfmCamera& camera) {
  const Eigen::Matrix3d R_world_camera = camera.pose().rotation().matrix();
  const Eigen::Matrix3d R = kFlip * R_world_camera.transpose();
  const Eigen::Vector3d t = -(kFlip * R_world_camera.transpose() * camera.pose().translation());
  carat::BalCamera c;
  c.head<3>() = carat::so3::log(Eigen::Quaterniond(R));
  c.segment<3>(3) = t;
  c[6] = camera.calibration().fx();
  c[7] = camera.calibration().k1();
  c[8] = camera.calibration().k2();
  return c;
}

gtsam::Key camera_key(std::size_t i) { return gtsam::Symbol('c', i); }
gtsam::Key point_key(std::size_t j) { return gtsam::Symbol('p', j); }

nlohmann::json run_gtsam_bal(const carat::BalProblem& bal, gtsam::Ordering::OrderingType order) {
  gtsam::NonlinearFactorGraph factors;
  const auto unit = gtsam::noiseModel::Unit::Create(2);
  for (const auto& o : bal.observations) {
    factors.emplace_shared<gtsam::GeneralSFMFactor<SfmCamera, gtsam::Point3>>(
        gtsam::Point2(o.x, -o.y), unit, camera_key(static_cast<std::size_t>(o.camera)),
        point_key(static_cast<std::size_t>(o.point)));
  }
  gtsam::Values initial;
  for (std::size_t i = 0; i < bal.cameras.size(); ++i) {
    initial.insert(camera_key(i), to_gtsam(bal.cameras[i]));
  }
  for (std::size_t j = 0; j < bal.points.size(); ++j) {
    initial.insert(point_key(j), gtsam::Point3(bal.points[j]));
  }
  gtsam::LevenbergMarquardtParams params;  // GTSAM's defaults
  params.orderingType = order;
  const carat::Stopwatch clock;
  gtsam::LevenbergMarquardtOptimizer optimizer(factors, initial, params);
  const gtsam::Values result = optimizer.optimize();
  const double seconds = clock.elapsed_s();
  carat::BalProblem solved = bal;
  for (std::size_t i = 0; i < bal.cameras.size(); ++i) {
    solved.cameras[i] = to_bal(result.at<SfmCamera>(camera_key(i)));
  }
  for (std::size_t j = 0; j < bal.points.size(); ++j) {
    solved.points[j] = result.at<gtsam::Point3>(point_key(j));
  }
  return {{"time_s", seconds},
          {"iterations", optimizer.iterations()},
          {"own_initial_error", factors.error(initial)},
          {"own_final_error", optimizer.error()},
          {"cost", carat::bal_cost(solved)}};
}

nlohmann::json run_carat_bal(const carat::BalProblem& bal) {
  carat::Problem problem;
  carat::add_bal_problem(bal, &problem);
  carat::SolverOptions options;
  options.num_threads = g_threads;
  const carat::Stopwatch clock;
  const carat::SolverSummary summary = carat::solve(options, problem);
  const double seconds = clock.elapsed_s();
  return {{"time_s", seconds},
          {"iterations", summary.num_iterations},
          {"termination", carat::to_string(summary.termination)},
          {"initial_cost", summary.initial_cost},
          {"cost", summary.final_cost}};
}

/// Runs every solver `repeat` times, interleaved; the best time and the last run's figures.
nlohmann::json interleave(
    const std::vector<std::pair<std::string, std::function<nlohmann::json()>>>& runners,
    int repeat) {
  nlohmann::json out;
  for (int r = 0; r < repeat; ++r) {
    for (const auto& [name, run_once] : runners) {
      nlohmann::json run = run_once();
      nlohmann::json& slot = out[name];
      slot["times_s"].push_back(run["time_s"]);
      const double t = run["time_s"].get<double>();
      slot["best_time_s"] =
          slot.contains("best_time_s") ? std::min(slot["best_time_s"].get<double>(), t) : t;
      run.erase("time_s");
      for (auto& [key, value] : run.items()) slot[key] = value;
    }
  }
  const double carat_time = out["carat"]["best_time_s"].get<double>();
  for (auto& [name, slot] : out.items()) {
    if (name != "carat") slot["carat_time_ratio"] = carat_time / slot["best_time_s"].get<double>();
  }
  return out;
}

int run_bal(int repeat, bool quick) {
  for (const SyntheticBalCase& c : synthetic_bal_cases(quick)) {
    const carat::BalProblem bal = carat::simulate_bal(c.options).problem;
    nlohmann::json j;
    j["problem"] = c.name;
    j["initial_cost"] = carat::bal_cost(bal);
    j["solvers"] =
        interleave({{"carat", [&] { return run_carat_bal(bal); }},
                    {"gtsam_default", [&] { return run_gtsam_bal(bal, gtsam::Ordering::COLAMD); }},
                    {"gtsam_metis", [&] { return run_gtsam_bal(bal, gtsam::Ordering::METIS); }}},
                   repeat);
    std::printf("%s\n", j.dump().c_str());
    std::fflush(stdout);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  carat::use_cpu_blas_kernels(argv);  // OpenBLAS's kernels for this CPU, as `carat` runs them
  int repeat = 3;
  bool bal = false;
  bool quick = false;
  std::vector<std::string> files;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--repeat" && i + 1 < argc) {
      repeat = std::max(1, std::atoi(argv[++i]));
    } else if (arg == "--threads" && i + 1 < argc) {
      g_threads = std::max(1, std::atoi(argv[++i]));
    } else if (arg == "--bal") {
      bal = true;
    } else if (arg == "--quick") {
      quick = true;
    } else if (!arg.empty() && arg[0] == '-') {
      std::fprintf(
          stderr,
          "usage: gtsam_compare [--repeat N] [--threads N] (FILE.g2o... | --bal [--quick])\n");
      return 2;
    } else {
      files.push_back(arg);
    }
  }
#ifdef GTSAM_USE_TBB
  const tbb::global_control tbb_threads(tbb::global_control::max_allowed_parallelism,
                                        static_cast<std::size_t>(g_threads));
  std::fprintf(stderr, "gtsam_compare: GTSAM with TBB, %d thread(s)\n", g_threads);
#else
  std::fprintf(stderr, "gtsam_compare: GTSAM without TBB (1 thread); carat %d thread(s)\n",
               g_threads);
#endif
  if (bal) return run_bal(repeat, quick);
  if (files.empty()) {
    std::fprintf(
        stderr,
        "usage: gtsam_compare [--repeat N] [--threads N] (FILE.g2o... | --bal [--quick])\n");
    return 2;
  }
  int exit_code = 0;
  for (const std::string& file : files) {
    nlohmann::json j;
    j["file"] = file;
    try {
      const carat::G2oGraph graph = carat::read_g2o_any(file);
      j["solvers"] = std::visit([&](const auto& g) { return compare(g, repeat); }, graph);
    } catch (const std::exception& e) {
      j["error"] = e.what();
      exit_code = 1;
    }
    std::printf("%s\n", j.dump().c_str());
    std::fflush(stdout);
  }
  return exit_code;
}
