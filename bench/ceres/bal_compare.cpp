// Side-by-side: Ceres 2.1 and carat solve the same synthetic bundle-adjustment problems (BAL
// format, Snavely camera model) in the same run.
// Ceres gets its standard setup for BAL (as in its bundle_adjuster example): one 9-parameter
// block per camera and one 3-parameter block per point, the reprojection error with automatic
// differentiation, LM, SPARSE_SCHUR (SuiteSparse; the elimination ordering Ceres picks), 1 thread,
// default tolerances and iteration limit. The cameras step as carat's do (the same layout): about
// their centre (--camera-steps centre, the default: carat's BalCameraManifold, given to Ceres as a
// ceres::Manifold) or added to their nine numbers (--camera-steps parameters, bundle_adjuster's
// own choice). Its time is Solve()'s own total. carat's time is the
// whole `carat solve-bal FILE --json` process, reading the file included (defaults, 1 thread);
// beside it, solve() alone in a child process with a user's own templated Snavely functor (one
// AutoDiffBlock per observation, Ceres's layout: carat_autodiff) and with carat's hand-written
// block (carat_shipped), points eliminated, default options, 1 thread.
// Each Ceres solve runs in a child process, once with the BLAS Debian's Ceres links and once
// with the system's (carat's) BLAS.
//
// Usage: bal_compare [--quick] [--keep DIR] [--camera-steps centre|parameters]
//   --quick: only the smallest problem. --keep: write the generated BAL files into DIR.
// Prints one JSON object per problem.
#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/LU>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <span>
#include <string>
#include <vector>

#include "../synthetic_bal_cases.hpp"
#include "carat/base/blas_kernels.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/residuals/bal_camera_manifold.hpp"
#include "carat/residuals/bal_problem.hpp"
#include "carat/residuals/io/bal_io.hpp"
#include "carat/sim/bal_scene.hpp"
#include "carat/solver/autodiff_block.hpp"
#include "carat/solver/lie_functions.hpp"
#include "carat/solver/solve.hpp"

namespace {

/// Whether cameras step about their centre (else added to their parameters), in every solver.
bool g_about_centre = true;

/// carat's BalCameraManifold as a ceres::Manifold: the same steps for Ceres.
class CameraAboutCentre final : public ceres::Manifold {
 public:
  int AmbientSize() const override { return 9; }
  int TangentSize() const override { return 9; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override {
    manifold_.plus(x, delta, x_plus_delta);
    return true;
  }
  bool PlusJacobian(const double* x, double* jacobian) const override {
    manifold_.plus_jacobian(x, jacobian);
    return true;
  }
  bool Minus(const double* y, const double* x, double* y_minus_x) const override {
    manifold_.minus(y, x, y_minus_x);
    return true;
  }
  bool MinusJacobian(const double* x, double* jacobian) const override {
    // d (y [-] x) / dy at y = x: the inverse of plus()'s Jacobian.
    Eigen::Matrix<double, 9, 9, Eigen::RowMajor> plus;
    manifold_.plus_jacobian(x, plus.data());
    Eigen::Map<Eigen::Matrix<double, 9, 9, Eigen::RowMajor>> out(jacobian);
    out = plus.inverse();
    return true;
  }

 private:
  carat::BalCameraManifold manifold_;
};

/// The BAL reprojection error: P = R(w) X + t, p = -P.xy / P.z, image = f (1 + k1 r^2 + k2 r^4) p.
struct ReprojectionError {
  double observed_x;
  double observed_y;

  template <typename T>
  bool operator()(const T* camera, const T* point, T* residual) const {
    T P[3];
    ceres::AngleAxisRotatePoint(camera, point, P);
    for (int k = 0; k < 3; ++k) P[k] += camera[3 + k];
    const T x = -P[0] / P[2];
    const T y = -P[1] / P[2];
    const T r2 = x * x + y * y;
    const T scale = camera[6] * (T(1.0) + r2 * (camera[7] + camera[8] * r2));
    residual[0] = scale * x - observed_x;
    residual[1] = scale * y - observed_y;
    return true;
  }
};

nlohmann::json run_ceres(const std::string& file) {
  carat::BalProblem bal = carat::read_bal(file);
  ceres::Problem problem;
  for (const auto& o : bal.observations) {
    auto* cost = new ceres::AutoDiffCostFunction<ReprojectionError, 2, 9, 3>(
        new ReprojectionError{o.x, o.y});
    problem.AddResidualBlock(cost, nullptr, bal.cameras[static_cast<std::size_t>(o.camera)].data(),
                             bal.points[static_cast<std::size_t>(o.point)].data());
  }
  if (g_about_centre) {
    for (auto& camera : bal.cameras) problem.SetManifold(camera.data(), new CameraAboutCentre);
  }
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::SPARSE_SCHUR;
  options.num_threads = 1;
  options.minimizer_progress_to_stdout = false;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  const carat::Stopwatch wall;
  ceres::Solve(options, &problem, &summary);
  const double wall_s = wall.elapsed_s();
  return {{"initial_cost", summary.initial_cost},
          {"final_cost", summary.final_cost},
          {"iterations", summary.num_successful_steps + summary.num_unsuccessful_steps},
          {"termination", ceres::TerminationTypeToString(summary.termination_type)},
          {"time_s", summary.total_time_in_seconds},
          {"wall_s", wall_s},
          {"linear_solver_time_s", summary.linear_solver_time_in_seconds},
          {"jacobian_time_s", summary.jacobian_evaluation_time_in_seconds}};
}

/// The same reprojection error as a carat user writes it: a functor templated on the scalar
/// (carat's lie::angle_axis_rotate, the same Rodrigues formula as Ceres's), one observation per
/// datum.
struct UserSnavely {
  template <typename T>
  bool operator()(const Eigen::Vector2d& observed, const T* camera, const T* point,
                  T* residual) const {
    T P[3];
    carat::lie::angle_axis_rotate(camera, point, P);
    for (int k = 0; k < 3; ++k) P[k] += camera[3 + k];
    const T x = -P[0] / P[2];
    const T y = -P[1] / P[2];
    const T r2 = x * x + y * y;
    const T scale = camera[6] * (T(1.0) + r2 * (camera[7] + camera[8] * r2));
    residual[0] = scale * x - observed.x();
    residual[1] = scale * y - observed.y();
    return true;
  }
};

/// carat in this process: the user's functor (one AutoDiffBlock per observation, the layout of
/// Ceres's bundle_adjuster) or carat's hand-written SnavelyReprojectionBlock (add_bal_problem()),
/// points eliminated by the Schur complement, default options, 1 thread. Time: solve() alone,
/// as Ceres's.
nlohmann::json run_carat(const std::string& file, bool autodiff) {
  const carat::BalProblem bal = carat::read_bal(file);
  carat::Problem problem;
  if (autodiff) {
    std::vector<carat::VariableId> cameras, points;
    const std::shared_ptr<const carat::Manifold> camera_manifold =
        g_about_centre ? carat::bal_camera_manifold() : carat::euclidean_manifold(9);
    for (const auto& c : bal.cameras) {
      cameras.push_back(
          problem.add_variable(camera_manifold, std::span<const double>(c.data(), 9)));
    }
    for (const auto& p : bal.points) {
      points.push_back(problem.add_euclidean(p));
      problem.set_eliminable(points.back());
    }
    for (const auto& o : bal.observations) {
      problem.add_residual_block(
          carat::make_autodiff_block<2, carat::VariableSize<9>, carat::VariableSize<3>>(
              UserSnavely{}, std::vector<Eigen::Vector2d>{Eigen::Vector2d(o.x, o.y)},
              {camera_manifold, nullptr}),
          {cameras[static_cast<std::size_t>(o.camera)], points[static_cast<std::size_t>(o.point)]});
    }
  } else {
    carat::add_bal_problem(bal, &problem, nullptr,
                           g_about_centre ? carat::BalCameraTangent::kAboutCentre
                                          : carat::BalCameraTangent::kParameters);
  }
  carat::SolverOptions options;
  options.num_threads = 1;
  const carat::Stopwatch wall;
  const carat::SolverSummary summary = carat::solve(options, problem);
  const double wall_s = wall.elapsed_s();
  return {{"initial_cost", summary.initial_cost},
          {"final_cost", summary.final_cost},
          {"iterations", summary.num_iterations},
          {"termination", carat::to_string(summary.termination)},
          {"time_s", wall_s},
          {"linearize_s", summary.time.linearize_s},
          {"cost_s", summary.time.cost_s}};
}

/// Runs `command`, returns its standard output; *wall_s: its wall time.
std::string run(const std::string& command, double* wall_s, int* status) {
  const carat::Stopwatch wall;
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) {
    *status = -1;
    return {};
  }
  std::string out;
  char buffer[4096];
  while (std::fgets(buffer, sizeof(buffer), pipe)) out += buffer;
  *status = pclose(pipe);
  *wall_s = wall.elapsed_s();
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  carat::use_cpu_blas_kernels(argv);  // OpenBLAS's kernels for this CPU, as `carat` runs them
  bool quick = false;
  std::string solver, file, keep;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--quick") {
      quick = true;
    } else if (arg == "--keep" && i + 1 < argc) {
      keep = argv[++i];
    } else if (arg == "--camera-steps" && i + 1 < argc &&
               (std::string(argv[i + 1]) == "centre" || std::string(argv[i + 1]) == "parameters")) {
      g_about_centre = std::string(argv[++i]) == "centre";
    } else if (arg == "--solver" && i + 2 < argc) {
      solver = argv[++i];
      file = argv[++i];
    } else {
      std::fprintf(
          stderr, "usage: bal_compare [--quick] [--keep DIR] [--camera-steps centre|parameters]\n");
      return 2;
    }
  }
  if (!solver.empty()) {  // child: one solve, one JSON line
    const nlohmann::json out = solver == "ceres"            ? run_ceres(file)
                               : solver == "carat-autodiff" ? run_carat(file, true)
                                                            : run_carat(file, false);
    std::printf("%s\n", out.dump().c_str());
    return 0;
  }
  const std::filesystem::path folder =
      keep.empty() ? std::filesystem::temp_directory_path() / "carat_bal_compare"
                   : std::filesystem::path(keep);
  std::filesystem::create_directories(folder);
  const std::string steps = g_about_centre ? "centre" : "parameters";
  // This program in a child process, with the same camera steps.
  const std::string self =
      "'" + std::filesystem::read_symlink("/proc/self/exe").string() + "' --camera-steps " + steps;
  const std::string system_blas = "libblas.so.3";  // see ceres_compare.cpp
  int exit_code = 0;
  for (const SyntheticBalCase& c : synthetic_bal_cases(quick)) {
    const carat::BalSimulationOptions& options = c.options;
    const carat::BalScene scene = carat::simulate_bal(options);
    const std::string path = (folder / (std::string(c.name) + ".bal")).string();
    carat::write_bal(path, scene.problem);

    nlohmann::json j;
    j["problem"] = c.name;
    j["camera_steps"] = steps;
    j["cameras"] = options.cameras;
    j["points"] = options.points;
    j["observations"] = scene.problem.observations.size();
    double wall_s = 0.0;
    int status = 0;
    const std::string ceres_out = run(self + " --solver ceres '" + path + "'", &wall_s, &status);
    const std::string ceres_blas_out =
        run("LD_PRELOAD='" + system_blas + "' " + self + " --solver ceres '" + path + "'", &wall_s,
            &status);
    int autodiff_status = 0, shipped_status = 0;
    double child_s = 0.0;
    const std::string autodiff_out =
        run(self + " --solver carat-autodiff '" + path + "'", &child_s, &autodiff_status);
    const std::string shipped_out =
        run(self + " --solver carat-shipped '" + path + "'", &child_s, &shipped_status);
    const std::string carat_out = run(
        "'" + std::string(CARAT_CLI) + "' solve-bal '" + path + "' --json --camera-steps " + steps,
        &wall_s, &status);
    if (status != 0 || autodiff_status != 0 || shipped_status != 0 || ceres_out.empty() ||
        ceres_blas_out.empty() || carat_out.empty() || autodiff_out.empty() ||
        shipped_out.empty()) {
      j["error"] = "a solver failed";
      std::printf("%s\n", j.dump().c_str());
      exit_code = 1;
      continue;
    }
    j["ceres"] = nlohmann::json::parse(ceres_out);
    j["ceres_system_blas"] = nlohmann::json::parse(ceres_blas_out);
    const nlohmann::json carat = nlohmann::json::parse(carat_out);
    j["carat"] = {{"initial_cost", carat["initial_cost"]},
                  {"final_cost", carat["final_cost"]},
                  {"iterations", carat["iterations"]},
                  {"termination", carat["termination"]},
                  {"process_s", wall_s},
                  {"time_s", carat["time_s"]},
                  {"time_breakdown", carat["time_breakdown"]}};
    const double ceres_time = std::min(j["ceres"]["time_s"].get<double>(),
                                       j["ceres_system_blas"]["time_s"].get<double>());
    const double ceres_cost = std::min(j["ceres"]["final_cost"].get<double>(),
                                       j["ceres_system_blas"]["final_cost"].get<double>());
    j["time_ratio_carat_process_over_ceres_solve"] = wall_s / ceres_time;
    // In-process solves: a user's templated functor, and carat's hand-written block.
    j["carat_autodiff"] = nlohmann::json::parse(autodiff_out);
    j["carat_shipped"] = nlohmann::json::parse(shipped_out);
    j["time_ratio_carat_autodiff_over_ceres_solve"] =
        j["carat_autodiff"]["time_s"].get<double>() / ceres_time;
    j["time_ratio_carat_shipped_over_ceres_solve"] =
        j["carat_shipped"]["time_s"].get<double>() / ceres_time;
    j["cost_ratio_carat_autodiff_over_ceres"] =
        j["carat_autodiff"]["final_cost"].get<double>() / ceres_cost;
    j["cost_ratio_carat_over_ceres"] = carat["final_cost"].get<double>() / ceres_cost;
    std::printf("%s\n", j.dump().c_str());
    std::fflush(stdout);
    if (keep.empty()) std::filesystem::remove(path);
  }
  return exit_code;
}
