#include "carat/registration/pose_graph_baseline.hpp"

#include <cmath>
#include <memory>
#include <numeric>
#include <string>

#include "carat/base/error.hpp"
#include "carat/residuals/pose_graph.hpp"
#include "carat/solver/solve.hpp"
#include "pose_covariances.hpp"

namespace carat {

const char* to_string(PoseGraphInformation information) {
  switch (information) {
    case PoseGraphInformation::kIdentity:
      return "identity";
    case PoseGraphInformation::kHessian:
      return "hessian";
  }
  return "unknown";
}

PoseGraphInformation parse_pose_graph_information(std::string_view name) {
  if (name == "identity") return PoseGraphInformation::kIdentity;
  if (name == "hessian") return PoseGraphInformation::kHessian;
  throw Error("unknown pose-graph information " + quote_bytes(name) +
              " (valid: identity, hessian)");
}

se3::Matrix6d relative_pose_information(const Eigen::Isometry3d& T_target_source,
                                        const se3::Matrix6d& H) {
  // A right perturbation exp([w, v]) of T_ij moves the factor's error e = [e_t, e_r] by
  // e_t = R_ij v and e_r = w, so [w, v] = M e with M = [0 I; R_ij^T 0].
  se3::Matrix6d M = se3::Matrix6d::Zero();
  M.block<3, 3>(0, 3).setIdentity();
  M.block<3, 3>(3, 0) = T_target_source.rotation().transpose();
  se3::Matrix6d information = M.transpose() * H * M;
  information = 0.5 * (information + information.transpose());
  // A pair whose geometry leaves a direction unconstrained gives a singular H; a ridge of 1e-9
  // of the largest diagonal entry keeps the factor usable (and that direction free in effect).
  information.diagonal().array() += 1e-9 * information.diagonal().maxCoeff();
  return information;
}

PoseGraphBaselineResult optimize_pose_graph_baseline(
    std::span<const Eigen::Isometry3d> T_world_initial,
    std::span<const PairRegistration> registrations, const PoseGraphBaselineOptions& options) {
  if (!(std::isfinite(options.cauchy_scale) && options.cauchy_scale >= 0.0)) {
    throw Error("pose graph: cauchy_scale must be finite and >= 0 (0: no kernel), got " +
                std::to_string(options.cauchy_scale));
  }
  // A frame whose pose rests on registrations that did not converge alone (no chain of converged
  // ones ties it to frame 0) would land where they put it, with CONVERGENCE reported.
  const std::size_t n = T_world_initial.size();
  std::vector<std::size_t> parent(n);
  std::iota(parent.begin(), parent.end(), std::size_t{0});
  const auto find = [&](std::size_t i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  std::size_t unconverged = 0;
  std::string named;
  for (const PairRegistration& r : registrations) {
    const auto i = static_cast<std::size_t>(r.pair.target),
               j = static_cast<std::size_t>(r.pair.source);
    if (i >= n || j >= n) continue;  // build_pose_graph_problem() names the missing frame
    if (r.converged) {
      parent[find(i)] = find(j);
    } else if (unconverged++ < 5) {
      named += (named.empty() ? "" : ", ") + std::string("(") + std::to_string(i) + ", " +
               std::to_string(j) + ")";
    }
  }
  std::size_t loose = 0, example = 0;
  for (std::size_t i = n; i-- > 1;) {
    if (find(i) == find(0)) continue;
    ++loose;
    example = i;
  }
  if (unconverged > 0 && loose > 0) {
    throw Error("pose graph: " + std::to_string(loose) + " frames (e.g. frame " +
                std::to_string(example) +
                ") are tied to frame 0 only through pair registrations that did not converge from "
                "the initial poses (" +
                std::to_string(unconverged) + " of " + std::to_string(registrations.size()) + ": " +
                named + (unconverged > 5 ? ", ..." : "") +
                "), so the graph would put them where those put them; start closer to the truth");
  }
  PoseGraph graph;
  for (std::size_t i = 0; i < T_world_initial.size(); ++i)
    graph.vertices.push_back({static_cast<std::int64_t>(i), T_world_initial[i]});
  for (const PairRegistration& r : registrations) {
    PoseGraph::Edge edge;
    edge.from = r.pair.target;
    edge.to = r.pair.source;
    edge.T_from_to = r.T_target_source;
    edge.information = options.information == PoseGraphInformation::kHessian
                           ? relative_pose_information(r.T_target_source, r.H)
                           : se3::Matrix6d::Identity();
    graph.edges.push_back(edge);
  }
  PoseGraphProblemOptions problem_options;
  if (options.cauchy_scale > 0.0)
    problem_options.loss = std::make_shared<CauchyLoss>(options.cauchy_scale);
  PoseGraphProblem built = build_pose_graph_problem(graph, problem_options);
  PoseGraphBaselineResult out;
  out.unconverged_pairs = unconverged;
  out.summary = solve(options.solver, built.problem);
  if (!out.summary.is_solution_usable())
    throw Error("pose-graph optimization failed: " + out.summary.message);
  if (options.covariance) {
    out.covariance = internal::pose_covariances(built.problem, built.vertex_variables,
                                                options.solver.num_threads, &out.covariance_s);
  }
  update_vertices(built, &graph);
  for (const auto& vertex : graph.vertices) out.T_world_frame.push_back(vertex.T_world_vertex);
  return out;
}

}  // namespace carat
