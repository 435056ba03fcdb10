// Side-by-side: Ceres 2.1 and carat solve the same g2o pose graph in the same run, each in its
// own child process so that each gets the BLAS it is built for (see main()).
// Ceres gets its standard setup for this problem (as in its pose_graph_3d example): one
// parameter block per pose = position + EigenQuaternionManifold (ProductManifold), the
// relative-pose cost with the square-root information (autodiff), LM,
// SPARSE_NORMAL_CHOLESKY with SuiteSparse, 1 thread, default tolerances, 200 iterations.
// carat solves the identical cost function (RelativePoseBlock), 1 thread, same limits.
// 2D graphs (VERTEX_SE2 / EDGE_SE2, e.g. intel and manhattan) get Ceres's pose_graph_2d setup:
// x, y and yaw parameter blocks, the yaw on a manifold that normalizes the angle to [-pi, pi),
// the residual [R_a^T (p_b - p_a) - p_ab; normalize(yaw_b - yaw_a - yaw_ab)] whitened by the
// upper-triangular U with U^T U = information (autodiff), the same solver settings. carat solves
// its RelativePoseSE2Block (whitened Log(Z^-1 T_a^-1 T_b)), which agrees with Ceres's residual
// to first order but is not the same function, so each solution is also evaluated under the
// other's cost ("cost_of_solution_under_*"), and Ceres solves carat's residual too
// ("ceres_same_cost": the identical cost function, the same settings).
//
// "carat_process" times the whole `carat solve-g2o FILE --json` process as a user runs it
// (wall clock, reading the file included) against Ceres's Solve() alone.
//
// Usage: ceres_compare [--repeat N] [FILE.g2o...]  (one JSON object per file and repeat)
#include <ceres/autodiff_manifold.h>
#include <ceres/ceres.h>
#include <ceres/manifold.h>
#include <ceres/product_manifold.h>

#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <type_traits>
#include <variant>
#include <vector>

#include "carat/base/blas_kernels.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/residuals/io/g2o_io.hpp"
#include "carat/residuals/pose_graph.hpp"
#include "carat/residuals/pose_graph_se2.hpp"
#include "carat/solver/se2.hpp"
#include "carat/solver/solve.hpp"
#include "json_child.hpp"
#include "pose_graph_error.hpp"

namespace {

nlohmann::json run_ceres(const carat::PoseGraph& graph) {
  using PoseManifold =
      ceres::ProductManifold<ceres::EuclideanManifold<3>, ceres::EigenQuaternionManifold>;
  std::vector<std::array<double, 7>> poses(graph.vertices.size());
  for (std::size_t i = 0; i < graph.vertices.size(); ++i) {
    const auto& T = graph.vertices[i].T_world_vertex;
    const Eigen::Quaterniond q(T.linear());
    poses[i] = {
        T.translation().x(), T.translation().y(), T.translation().z(), q.x(), q.y(), q.z(), q.w()};
  }
  ceres::Problem::Options problem_options;
  ceres::Problem problem(problem_options);
  for (const auto& edge : graph.edges) {
    const Eigen::Matrix<double, 6, 6> sqrt_info = edge.information.llt().matrixU();
    auto* cost = new ceres::AutoDiffCostFunction<PoseGraphError, 6, 7, 7>(new PoseGraphError(
        edge.T_from_to.translation(), Eigen::Quaterniond(edge.T_from_to.linear()), sqrt_info));
    problem.AddResidualBlock(cost, nullptr,
                             poses[static_cast<std::size_t>(graph.index_of(edge.from))].data(),
                             poses[static_cast<std::size_t>(graph.index_of(edge.to))].data());
  }
  for (auto& pose : poses) problem.SetManifold(pose.data(), new PoseManifold);
  problem.SetParameterBlockConstant(poses.front().data());

  ceres::Solver::Options options;
  options.max_num_iterations = 200;
  options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  options.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
  options.minimizer_type = ceres::TRUST_REGION;
  options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  options.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  return {{"initial_cost", summary.initial_cost},
          {"final_cost", summary.final_cost},
          {"iterations", summary.iterations.size() - 1},
          {"termination", ceres::TerminationTypeToString(summary.termination_type)},
          {"time_s", summary.total_time_in_seconds},
          {"linear_solver_time_s", summary.linear_solver_time_in_seconds},
          {"jacobian_evaluation_time_s", summary.jacobian_evaluation_time_in_seconds}};
}

nlohmann::json run_carat(const carat::PoseGraph& graph) {
  carat::PoseGraphProblem built = carat::build_pose_graph_problem(graph);
  carat::SolverOptions options;
  options.max_iterations = 200;
  options.num_threads = 1;
  const carat::SolverSummary summary = carat::solve(options, built.problem);
  return {{"initial_cost", summary.initial_cost},
          {"final_cost", summary.final_cost},
          {"iterations", summary.num_iterations},
          {"termination", carat::to_string(summary.termination)},
          {"time_s", summary.time.total_s},
          {"linear_solver_time_s",
           summary.time.numeric_s + summary.time.solve_s + summary.time.symbolic_s}};
}

/// The angle (radians) in [-pi, pi), as Ceres's pose_graph_2d normalizes it.
template <typename T>
T normalize_angle(const T& angle) {
  const T two_pi(2.0 * EIGEN_PI);
  return angle - two_pi * ceres::floor((angle + T(EIGEN_PI)) / two_pi);
}

/// Ceres's yaw manifold: plus and minus through normalize_angle.
struct AngleManifold {
  template <typename T>
  bool Plus(const T* x, const T* delta, T* x_plus_delta) const {
    *x_plus_delta = normalize_angle(*x + *delta);
    return true;
  }
  template <typename T>
  bool Minus(const T* y, const T* x, T* y_minus_x) const {
    *y_minus_x = normalize_angle(*y) - normalize_angle(*x);
    return true;
  }
};

/// Ceres's planar pose-graph residual [R_a^T (p_b - p_a) - p_ab; normalize(yaw_b - yaw_a -
/// yaw_ab)], whitened.
struct PoseGraph2dError {
  PoseGraph2dError(const Eigen::Vector2d& p_ab, double yaw_ab,
                   const Eigen::Matrix3d& sqrt_information)
      : p_ab_(p_ab), yaw_ab_(yaw_ab), sqrt_information_(sqrt_information) {}

  template <typename T>
  bool operator()(const T* x_a, const T* y_a, const T* yaw_a, const T* x_b, const T* y_b,
                  const T* yaw_b, T* residuals) const {
    const Eigen::Matrix<T, 2, 1> p_a(*x_a, *y_a);
    const Eigen::Matrix<T, 2, 1> p_b(*x_b, *y_b);
    const T c = ceres::cos(*yaw_a), s = ceres::sin(*yaw_a);
    Eigen::Matrix<T, 2, 2> R_a;
    R_a << c, -s, s, c;
    Eigen::Map<Eigen::Matrix<T, 3, 1>> r(residuals);
    r.template head<2>() = R_a.transpose() * (p_b - p_a) - p_ab_.template cast<T>();
    r(2) = normalize_angle((*yaw_b - *yaw_a) - T(yaw_ab_));
    r.applyOnTheLeft(sqrt_information_.template cast<T>());
    return true;
  }

  Eigen::Vector2d p_ab_;
  double yaw_ab_;
  Eigen::Matrix3d sqrt_information_;
};

/// carat's RelativePoseSE2Block written for Ceres: whitened Log(Z_ab^-1 T_a^-1 T_b) in the order
/// (x, y, theta), with the SE(2) logarithm's V^-1 on the translation, so that Ceres minimizes the
/// identical cost function.
struct SameAsCaratSE2Error {
  SameAsCaratSE2Error(const Eigen::Vector2d& p_ab, double yaw_ab,
                      const Eigen::Matrix3d& sqrt_information)
      : p_ab_(p_ab), yaw_ab_(yaw_ab), sqrt_information_(sqrt_information) {}

  template <typename T>
  bool operator()(const T* x_a, const T* y_a, const T* yaw_a, const T* x_b, const T* y_b,
                  const T* yaw_b, T* residuals) const {
    const T ca = ceres::cos(*yaw_a), sa = ceres::sin(*yaw_a);
    const T dx = ca * (*x_b - *x_a) + sa * (*y_b - *y_a);  // T_a^-1 T_b
    const T dy = -sa * (*x_b - *x_a) + ca * (*y_b - *y_a);
    const double cz = std::cos(yaw_ab_), sz = std::sin(yaw_ab_);
    const T ex = cz * (dx - p_ab_.x()) + sz * (dy - p_ab_.y());  // Z_ab^-1 T_a^-1 T_b
    const T ey = -sz * (dx - p_ab_.x()) + cz * (dy - p_ab_.y());
    const T w = normalize_angle((*yaw_b - *yaw_a) - T(yaw_ab_));
    T a, b;  // V(w) = [a -b; b a]: a = sin(w) / w, b = (1 - cos(w)) / w
    if (ceres::abs(w) < T(1e-6)) {
      a = T(1.0) - w * w / T(6.0);
      b = w / T(2.0) - w * w * w / T(24.0);
    } else {
      a = ceres::sin(w) / w;
      b = (T(1.0) - ceres::cos(w)) / w;
    }
    const T n = a * a + b * b;
    Eigen::Map<Eigen::Matrix<T, 3, 1>> r(residuals);
    r(0) = (a * ex + b * ey) / n;
    r(1) = (-b * ex + a * ey) / n;
    r(2) = w;
    r.applyOnTheLeft(sqrt_information_.template cast<T>());
    return true;
  }

  Eigen::Vector2d p_ab_;
  double yaw_ab_;
  Eigen::Matrix3d sqrt_information_;
};

/// 1/2 sum |r|^2 of Ceres's planar residuals at the given poses (x, y, yaw per vertex).
double ceres_cost_se2(const carat::PoseGraphSE2& graph,
                      const std::vector<std::array<double, 3>>& poses) {
  double cost = 0.0;
  for (const auto& edge : graph.edges) {
    const auto& a = poses[static_cast<std::size_t>(graph.index_of(edge.from))];
    const auto& b = poses[static_cast<std::size_t>(graph.index_of(edge.to))];
    const PoseGraph2dError error(edge.T_from_to.translation(), carat::se2::angle(edge.T_from_to),
                                 edge.information.llt().matrixU());
    double r[3];
    error(&a[0], &a[1], &a[2], &b[0], &b[1], &b[2], r);
    cost += 0.5 * (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
  }
  return cost;
}

/// 1/2 sum |r|^2 of carat's RelativePoseSE2Block residuals at the given poses.
double carat_cost_se2(carat::PoseGraphSE2 graph, const std::vector<std::array<double, 3>>& poses) {
  for (std::size_t i = 0; i < graph.vertices.size(); ++i) {
    graph.vertices[i].T_world_vertex = carat::se2::make(poses[i][0], poses[i][1], poses[i][2]);
  }
  return carat::build_pose_graph_problem(graph).problem.evaluate_cost();
}

nlohmann::json run_ceres(const carat::PoseGraphSE2& graph, bool same_cost_as_carat) {
  std::vector<std::array<double, 3>> poses(graph.vertices.size());
  for (std::size_t i = 0; i < graph.vertices.size(); ++i) {
    carat::se2::to_storage(graph.vertices[i].T_world_vertex, poses[i].data());
  }
  ceres::Problem::Options problem_options;
  ceres::Problem problem(problem_options);
  for (const auto& edge : graph.edges) {
    auto& a = poses[static_cast<std::size_t>(graph.index_of(edge.from))];
    auto& b = poses[static_cast<std::size_t>(graph.index_of(edge.to))];
    const Eigen::Matrix3d sqrt_info = edge.information.llt().matrixU();
    ceres::CostFunction* cost = nullptr;
    if (same_cost_as_carat) {
      cost = new ceres::AutoDiffCostFunction<SameAsCaratSE2Error, 3, 1, 1, 1, 1, 1, 1>(
          new SameAsCaratSE2Error(edge.T_from_to.translation(), carat::se2::angle(edge.T_from_to),
                                  sqrt_info));
    } else {
      cost = new ceres::AutoDiffCostFunction<PoseGraph2dError, 3, 1, 1, 1, 1, 1, 1>(
          new PoseGraph2dError(edge.T_from_to.translation(), carat::se2::angle(edge.T_from_to),
                               sqrt_info));
    }
    problem.AddResidualBlock(cost, nullptr, &a[0], &a[1], &a[2], &b[0], &b[1], &b[2]);
  }
  for (auto& pose : poses) {
    if (problem.HasParameterBlock(&pose[2])) {
      problem.SetManifold(&pose[2], new ceres::AutoDiffManifold<AngleManifold, 1, 1>);
    }
  }
  for (double& value : poses.front()) problem.SetParameterBlockConstant(&value);

  ceres::Solver::Options options;
  options.max_num_iterations = 200;
  options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  options.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
  options.minimizer_type = ceres::TRUST_REGION;
  options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  options.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  return {{"initial_cost", summary.initial_cost},
          {"final_cost", summary.final_cost},
          {"cost_of_solution_under_carat", carat_cost_se2(graph, poses)},
          {"iterations", summary.iterations.size() - 1},
          {"termination", ceres::TerminationTypeToString(summary.termination_type)},
          {"time_s", summary.total_time_in_seconds},
          {"linear_solver_time_s", summary.linear_solver_time_in_seconds},
          {"jacobian_evaluation_time_s", summary.jacobian_evaluation_time_in_seconds}};
}

nlohmann::json run_carat(const carat::PoseGraphSE2& graph) {
  carat::PoseGraphProblem built = carat::build_pose_graph_problem(graph);
  carat::SolverOptions options;
  options.max_iterations = 200;
  options.num_threads = 1;
  const carat::SolverSummary summary = carat::solve(options, built.problem);
  std::vector<std::array<double, 3>> poses(graph.vertices.size());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    carat::se2::to_storage(built.problem.se2(built.vertex_variables[i]), poses[i].data());
  }
  return {{"initial_cost", summary.initial_cost},
          {"final_cost", summary.final_cost},
          {"cost_of_solution_under_ceres", ceres_cost_se2(graph, poses)},
          {"iterations", summary.num_iterations},
          {"termination", carat::to_string(summary.termination)},
          {"time_s", summary.time.total_s},
          {"linear_solver_time_s",
           summary.time.numeric_s + summary.time.solve_s + summary.time.symbolic_s}};
}

}  // namespace

/// The whole `carat solve-g2o FILE --json` process (starting it, reading and parsing the file,
/// building, solving, printing), wall-clock seconds beside its final cost and iterations.
nlohmann::json run_carat_process(const std::string& file) {
  const carat::Stopwatch clock;
  const nlohmann::json out = run_json_child(
      "'" + std::string(CARAT_CLI) + "' solve-g2o '" + file + "' --max-iterations 200 --json", "");
  const double wall_s = clock.elapsed_s();
  if (out.contains("error")) return out;
  return {{"wall_s", wall_s},
          {"final_cost", out["final_cost"]},
          {"iterations", out["iterations"]},
          {"solve_time_s", out["time_s"]}};
}

/// Runs one solver in a child process (this program with --solver) and returns its JSON line.
/// `preload` (may be empty) goes into LD_PRELOAD, which decides which BLAS CHOLMOD's dgemm_
/// and friends resolve to in that process.
nlohmann::json run_child(const std::string& self, const std::string& solver,
                         const std::string& file, const std::string& preload) {
  return run_json_child("'" + self + "' --solver " + solver + " '" + file + "'", preload);
}

int main(int argc, char** argv) {
  carat::use_cpu_blas_kernels(argv);  // OpenBLAS's kernels for this CPU, as `carat` runs them
  int repeat = 1;
  std::string solver;
  std::vector<std::string> files;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--repeat" && i + 1 < argc) {
      repeat = std::stoi(argv[++i]);
    } else if (arg == "--solver" && i + 1 < argc) {
      solver = argv[++i];
    } else {
      files.push_back(arg);
    }
  }
  if (files.empty()) {
    for (const char* name : {"sphere2500", "parking-garage", "torus3D", "intel", "manhattan"}) {
      files.push_back(std::string(CARAT_DATA_DIR) + "/posegraph/" + name + ".g2o");
    }
  }
  if (!solver.empty()) {  // child: solve one file with one solver, print one JSON line
    const carat::G2oGraph any = carat::read_g2o_any(files.front());
    const nlohmann::json j = std::visit(
        [&](const auto& graph) -> nlohmann::json {
          if (solver == "carat") return run_carat(graph);
          if constexpr (std::is_same_v<std::decay_t<decltype(graph)>, carat::PoseGraphSE2>) {
            return run_ceres(graph, solver == "ceres-same-cost");
          } else {
            return run_ceres(graph);  // the 3D residual is already carat's
          }
        },
        any);
    std::printf("%s\n", j.dump().c_str());
    return 0;
  }
  const std::string self = std::filesystem::read_symlink("/proc/self/exe").string();
  // carat's BLAS is the system's libblas.so.3 (OpenBLAS serial after scripts/install-deps.sh).
  // Debian's libceres links ATLAS's libf77blas.so.3 directly, so in a process that loads
  // Ceres, dgemm_ resolves to ATLAS unless libblas.so.3 is preloaded.
  const std::string system_blas = "libblas.so.3";
  for (const auto& file : files) {
    if (!std::filesystem::exists(file)) {
      std::fprintf(stderr, "ceres_compare: skipping %s: not found\n", file.c_str());
      continue;
    }
    const carat::G2oGraph any = carat::read_g2o_any(file);
    const auto [vertices, edges] = std::visit(
        [](const auto& graph) { return std::pair(graph.vertices.size(), graph.edges.size()); },
        any);
    for (int r = 0; r < repeat; ++r) {
      nlohmann::json j;
      j["file"] = file;
      j["dimension"] = any.index() == 1 ? 2 : 3;
      j["vertices"] = vertices;
      j["edges"] = edges;
      j["ceres"] = run_child(self, "ceres", file, "");                       // as Debian ships it
      j["ceres_system_blas"] = run_child(self, "ceres", file, system_blas);  // same BLAS as carat
      j["carat"] = run_child(self, "carat", file, system_blas);
      j["carat_process"] = run_carat_process(file);
      if (j["ceres"].contains("error") || j["carat"].contains("error") ||
          j["ceres_system_blas"].contains("error") || j["carat_process"].contains("error")) {
        std::printf("%s\n", j.dump().c_str());
        return 1;
      }
      const double carat_cost = j["carat"]["final_cost"];
      const double carat_time = j["carat"]["time_s"];
      j["cost_ratio_carat_over_ceres"] = carat_cost / j["ceres"]["final_cost"].get<double>();
      j["time_ratio_carat_over_ceres"] = carat_time / j["ceres"]["time_s"].get<double>();
      j["time_ratio_carat_over_ceres_system_blas"] =
          carat_time / j["ceres_system_blas"]["time_s"].get<double>();
      // Whole process against Ceres's Solve() alone (its reading and building not counted).
      j["time_ratio_carat_process_over_ceres"] =
          j["carat_process"]["wall_s"].get<double>() / j["ceres"]["time_s"].get<double>();
      j["time_ratio_carat_process_over_ceres_system_blas"] =
          j["carat_process"]["wall_s"].get<double>() /
          j["ceres_system_blas"]["time_s"].get<double>();
      if (j["dimension"] == 2) {  // Ceres on carat's own residual: the same cost function
        j["ceres_same_cost"] = run_child(self, "ceres-same-cost", file, "");
        if (j["ceres_same_cost"].contains("error")) {
          std::printf("%s\n", j.dump().c_str());
          return 1;
        }
        j["cost_ratio_carat_over_ceres_same_cost"] =
            carat_cost / j["ceres_same_cost"]["final_cost"].get<double>();
        j["time_ratio_carat_over_ceres_same_cost"] =
            carat_time / j["ceres_same_cost"]["time_s"].get<double>();
      }
      std::printf("%s\n", j.dump().c_str());
      std::fflush(stdout);
    }
  }
  return 0;
}
