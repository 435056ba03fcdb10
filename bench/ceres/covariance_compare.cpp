// Side by side: the covariance of every pose of a 3D g2o pose graph from carat::Covariance and
// from Ceres 2.1's Covariance (SPARSE_QR, its default), at the same point, in the same run.
//
// carat solves the graph (LM, 1 thread, 200 iterations; the first vertex or the FIX records held
// constant), writes the solution, and times Covariance over every free pose; Ceres takes that
// solution in its pose_graph_3d setup (position + EigenQuaternionManifold, the relative-pose
// residual that carat's RelativePoseBlock also computes, so both have the same Gauss-Newton
// Hessian up to the change of tangent coordinates) and times Covariance::Compute() over every
// free pose's (i, i) block, 1 thread. Each runs in its own child process, as in ceres_compare:
// carat and "ceres_system_blas" with the system's libblas.so.3 preloaded, "ceres" as Debian ships
// it.
//
// Tangents: Ceres moves a pose by [dp, dq] with p <- p + dp and q <- [cos|dq|, sin|dq| dq/|dq|] q
// (a rotation by 2 dq on the left); carat by xi = [omega, v], T <- T Exp(xi). At first order
// dp = R v and dq = R omega / 2, so Sigma_carat = M Sigma_ceres M^T with M = [0, 2 R^T; R^T, 0].
// Every block is compared after that conversion: max over poses of |C_carat - C_ceres|_F /
// |C_ceres|_F.
//
// Usage: covariance_compare [FILE.g2o...]  (one JSON object per file; parking-garage and
// sphere2500 from the data folder by default)
#include <ceres/ceres.h>
#include <ceres/covariance.h>
#include <ceres/manifold.h>
#include <ceres/product_manifold.h>
#include <sys/resource.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "carat/base/blas_kernels.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/residuals/io/g2o_io.hpp"
#include "carat/residuals/pose_graph.hpp"
#include "carat/solver/covariance.hpp"
#include "carat/solver/se3.hpp"
#include "carat/solver/solve.hpp"
#include "json_child.hpp"
#include "pose_graph_error.hpp"

namespace {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

/// CPU seconds of this process so far (user + system).
double cpu_seconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

/// One pose per line: "constant qx qy qz qw tx ty tz".
struct Pose {
  bool constant = false;
  std::array<double, 7> q_t{};
};

void write_poses(const std::string& path, const std::vector<Pose>& poses) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  for (const Pose& pose : poses) {
    std::fprintf(f, "%d", pose.constant ? 1 : 0);
    for (double x : pose.q_t) std::fprintf(f, " %.17g", x);
    std::fprintf(f, "\n");
  }
  std::fclose(f);
}

std::vector<Pose> read_poses(const std::string& path) {
  std::ifstream in(path);
  std::vector<Pose> poses;
  Pose pose;
  int constant = 0;
  while (in >> constant) {
    pose.constant = constant != 0;
    for (double& x : pose.q_t) in >> x;
    poses.push_back(pose);
  }
  return poses;
}

void write_blocks(const std::string& path, const std::vector<Matrix6d>& blocks) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(blocks.data()),
            static_cast<std::streamsize>(blocks.size() * sizeof(Matrix6d)));
}

std::vector<Matrix6d> read_blocks(const std::string& path, std::size_t count) {
  std::vector<Matrix6d> blocks(count);
  std::ifstream in(path, std::ios::binary);
  in.read(reinterpret_cast<char*>(blocks.data()),
          static_cast<std::streamsize>(count * sizeof(Matrix6d)));
  if (!in) blocks.clear();
  return blocks;
}

/// carat: solve, write the solution, time the covariance of every free pose, write the blocks.
nlohmann::json run_carat(const carat::PoseGraph& graph, const std::string& poses_path,
                         const std::string& blocks_path) {
  carat::PoseGraphProblem built = carat::build_pose_graph_problem(graph);
  carat::SolverOptions options;
  options.max_iterations = 200;
  options.num_threads = 1;
  const carat::SolverSummary summary = carat::solve(options, built.problem);
  std::vector<Pose> poses(graph.vertices.size());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const carat::VariableId v = built.vertex_variables[i];
    poses[i].constant = built.problem.is_constant(v);
    carat::se3::to_storage(built.problem.se3(v), poses[i].q_t.data());
  }
  write_poses(poses_path, poses);

  const double cpu0 = cpu_seconds();
  const carat::Stopwatch wall;
  const carat::Covariance covariance(built.problem);
  std::vector<Matrix6d> blocks(poses.size(), Matrix6d::Zero());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    if (!poses[i].constant) blocks[i] = covariance.block(built.vertex_variables[i]);
  }
  const double covariance_s = wall.elapsed_s();
  const double covariance_cpu_s = cpu_seconds() - cpu0;
  write_blocks(blocks_path, blocks);
  return {{"final_cost", summary.final_cost},
          {"solve_time_s", summary.time.total_s},
          {"numeric_factorization_s", summary.time.numeric_s},
          {"factorizations", summary.num_iterations},
          {"covariance_s", covariance_s},
          {"covariance_cpu_s", covariance_cpu_s},
          {"covariance_breakdown",
           {{"linearize_s", covariance.time().linearize_s},
            {"factorize_s", covariance.time().factorize_s},
            {"sparse_inverse_s", covariance.time().inverse_s}}},
          {"factorization", covariance.description()}};
}

/// Ceres: the covariance of every free pose at carat's solution, converted to carat's tangent.
nlohmann::json run_ceres(const carat::PoseGraph& graph, const std::string& poses_path,
                         const std::string& blocks_path) {
  using PoseManifold =
      ceres::ProductManifold<ceres::EuclideanManifold<3>, ceres::EigenQuaternionManifold>;
  const std::vector<Pose> solved = read_poses(poses_path);
  if (solved.size() != graph.vertices.size()) return {{"error", "bad poses file"}};
  std::vector<std::array<double, 7>> poses(solved.size());  // [p, q (x, y, z, w)]
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const auto& s = solved[i].q_t;
    poses[i] = {s[4], s[5], s[6], s[0], s[1], s[2], s[3]};
  }
  ceres::Problem problem;
  for (const auto& edge : graph.edges) {
    const Matrix6d sqrt_info = edge.information.llt().matrixU();
    auto* cost = new ceres::AutoDiffCostFunction<PoseGraphError, 6, 7, 7>(new PoseGraphError(
        edge.T_from_to.translation(), Eigen::Quaterniond(edge.T_from_to.linear()), sqrt_info));
    problem.AddResidualBlock(cost, nullptr,
                             poses[static_cast<std::size_t>(graph.index_of(edge.from))].data(),
                             poses[static_cast<std::size_t>(graph.index_of(edge.to))].data());
  }
  std::vector<std::pair<const double*, const double*>> pairs;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    problem.SetManifold(poses[i].data(), new PoseManifold);
    if (solved[i].constant) {
      problem.SetParameterBlockConstant(poses[i].data());
    } else {
      pairs.emplace_back(poses[i].data(), poses[i].data());
    }
  }
  ceres::Covariance::Options options;  // SPARSE_QR
  options.num_threads = 1;
  ceres::Covariance covariance(options);
  const double cpu0 = cpu_seconds();
  const carat::Stopwatch wall;
  const bool ok = covariance.Compute(pairs, &problem);
  std::vector<Matrix6d> blocks(poses.size(), Matrix6d::Zero());
  for (std::size_t i = 0; ok && i < poses.size(); ++i) {
    if (solved[i].constant) continue;
    Eigen::Matrix<double, 6, 6, Eigen::RowMajor> ceres_block;
    covariance.GetCovarianceBlockInTangentSpace(poses[i].data(), poses[i].data(),
                                                ceres_block.data());
    blocks[i] = ceres_block;
  }
  const double covariance_s = wall.elapsed_s();
  const double covariance_cpu_s = cpu_seconds() - cpu0;
  if (!ok) return {{"error", "ceres::Covariance::Compute failed"}};
  // To carat's tangent: Sigma_carat = M Sigma_ceres M^T, M = [0, 2 R^T; R^T, 0].
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const Eigen::Matrix3d R = carat::se3::from_storage(solved[i].q_t.data()).linear();
    Matrix6d M = Matrix6d::Zero();
    M.block<3, 3>(0, 3) = 2.0 * R.transpose();
    M.block<3, 3>(3, 0) = R.transpose();
    blocks[i] = M * blocks[i] * M.transpose();
  }
  write_blocks(blocks_path, blocks);
  return {{"algorithm", "SPARSE_QR"},
          {"covariance_s", covariance_s},
          {"covariance_cpu_s", covariance_cpu_s}};
}

/// Runs this program as a child for one solver; returns its JSON line.
nlohmann::json run_child(const std::string& self, const std::string& solver,
                         const std::string& file, const std::string& poses,
                         const std::string& blocks, const std::string& preload) {
  return run_json_child("'" + self + "' --solver " + solver + " --poses '" + poses +
                            "' --blocks '" + blocks + "' '" + file + "'",
                        preload);
}

/// Largest |A_i - B_i|_F / |B_i|_F over the free poses (B_i nonzero).
double max_relative_difference(const std::vector<Matrix6d>& a, const std::vector<Matrix6d>& b) {
  double worst = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const double norm = b[i].norm();
    if (norm > 0.0) worst = std::max(worst, (a[i] - b[i]).norm() / norm);
  }
  return worst;
}

}  // namespace

int main(int argc, char** argv) {
  carat::use_cpu_blas_kernels(argv);  // OpenBLAS's kernels for this CPU, as `carat` runs them
  std::string solver, poses_path, blocks_path;
  std::vector<std::string> files;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--solver" && i + 1 < argc) {
      solver = argv[++i];
    } else if (arg == "--poses" && i + 1 < argc) {
      poses_path = argv[++i];
    } else if (arg == "--blocks" && i + 1 < argc) {
      blocks_path = argv[++i];
    } else {
      files.push_back(arg);
    }
  }
  if (files.empty()) {
    for (const char* name : {"parking-garage", "sphere2500"}) {
      files.push_back(std::string(CARAT_DATA_DIR) + "/posegraph/" + name + ".g2o");
    }
  }
  if (!solver.empty()) {  // child
    const carat::PoseGraph graph = carat::read_g2o(files.front());
    const nlohmann::json j = solver == "carat" ? run_carat(graph, poses_path, blocks_path)
                                               : run_ceres(graph, poses_path, blocks_path);
    std::printf("%s\n", j.dump().c_str());
    return j.contains("error") ? 1 : 0;
  }
  const std::string self = std::filesystem::read_symlink("/proc/self/exe").string();
  const std::string system_blas = "libblas.so.3";  // see ceres_compare.cpp
  const std::filesystem::path scratch =
      std::filesystem::temp_directory_path() / ("covariance_compare." + std::to_string(getpid()));
  std::filesystem::create_directories(scratch);
  int status = 0;
  for (const auto& file : files) {
    if (!std::filesystem::exists(file)) {
      std::fprintf(stderr, "covariance_compare: skipping %s: not found\n", file.c_str());
      continue;
    }
    const carat::PoseGraph graph = carat::read_g2o(file);
    const std::string poses = (scratch / "poses.txt").string();
    const std::string carat_blocks = (scratch / "carat.bin").string();
    const std::string ceres_blocks = (scratch / "ceres.bin").string();
    nlohmann::json j;
    j["file"] = file;
    j["vertices"] = graph.vertices.size();
    j["edges"] = graph.edges.size();
    j["carat"] = run_child(self, "carat", file, poses, carat_blocks, system_blas);
    j["ceres"] = run_child(self, "ceres", file, poses, ceres_blocks, "");
    const auto a = read_blocks(carat_blocks, graph.vertices.size());
    const auto b = read_blocks(ceres_blocks, graph.vertices.size());
    j["ceres_system_blas"] = run_child(self, "ceres", file, poses, ceres_blocks, system_blas);
    if (j["carat"].contains("error") || j["ceres"].contains("error") ||
        j["ceres_system_blas"].contains("error") || a.empty() || b.empty()) {
      std::printf("%s\n", j.dump().c_str());
      status = 1;
      continue;
    }
    j["max_block_relative_difference"] = max_relative_difference(a, b);
    const double carat_s = j["carat"]["covariance_s"];
    j["time_ratio_carat_over_ceres"] = carat_s / j["ceres"]["covariance_s"].get<double>();
    j["time_ratio_carat_over_ceres_system_blas"] =
        carat_s / j["ceres_system_blas"]["covariance_s"].get<double>();
    j["time_ratio_covariance_over_carat_solve"] =
        carat_s / j["carat"]["solve_time_s"].get<double>();
    std::printf("%s\n", j.dump().c_str());
    std::fflush(stdout);
  }
  std::filesystem::remove_all(scratch);
  return status;
}
