// carat.solve_g2o: a 3-D or 2-D g2o pose graph solved from Python (and, when asked, the
// covariance of every free vertex at the solution).
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <filesystem>
#include <optional>
#include <string>
#include <type_traits>
#include <variant>
#include <vector>

#include "arrays.hpp"
#include "bindings.hpp"
#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/residuals/io/g2o_io.hpp"
#include "carat/residuals/pose_graph.hpp"
#include "carat/residuals/pose_graph_se2.hpp"
#include "carat/solver/covariance.hpp"
#include "carat/solver/loss_function.hpp"
#include "carat/solver/solve.hpp"
#include "integer_arguments.hpp"
#include "interrupt.hpp"
#include "mapping_types.hpp"

namespace carat::python {

namespace {

py::dict solve_g2o(const std::filesystem::path& path, int max_iterations, int threads,
                   const std::string& method_name, const std::string& loss_name, double loss_scale,
                   const std::string& ordering, bool repair_information,
                   const std::optional<std::filesystem::path>& out, bool covariance,
                   const std::string& covariance_gauge) {
  SolverOptions options;
  options.max_iterations = max_iterations;
  options.num_threads = threads_argument(threads);
  options.method = parse_method(method_name);
  options.ordering = parse_ordering(ordering);
  const LossKind loss = parse_loss_kind(loss_name);
  Covariance::Options covariance_options;
  covariance_options.gauge = parse_covariance_gauge(covariance_gauge);
  covariance_options.num_threads = options.num_threads;
  if (out && std::filesystem::exists(*out) && std::filesystem::equivalent(*out, path)) {
    throw Error(out->string() + ": the output would overwrite the input graph");
  }
  G2oReadOptions read_options;
  if (repair_information) read_options.information = InformationRepair::kNearest;
  struct Solved {
    SolverSummary summary;
    std::size_t vertices = 0;
    std::size_t edges = 0;
    int dimension = 3;
    std::vector<std::int64_t> ids;        // free vertices, with covariance
    std::vector<Eigen::MatrixXd> blocks;  // their covariances
    double covariance_s = 0.0;
  };
  const Solved solved = run_released([&](InterruptCheck& check) {
    options.iteration_callback = check.iteration_callback();
    G2oGraph any = read_g2o_any(path, read_options);
    return std::visit(
        [&](auto& graph) {
          using Graph = std::decay_t<decltype(graph)>;
          PoseGraphProblemOptions problem_options;
          problem_options.loss = make_loss(loss, loss_scale);
          PoseGraphProblem built;
          try {
            built = build_pose_graph_problem(graph, problem_options);
          } catch (const Error& e) {
            throw Error(path.string() + ": " + e.what());
          }
          Solved s;
          s.summary = solve(options, built.problem);
          if (s.summary.termination == TerminationType::kUserAbort) throw Interrupted{};
          if (s.summary.termination == TerminationType::kFailure) {
            throw Error(path.string() + ": the solve failed: " + s.summary.message);
          }
          s.vertices = graph.vertices.size();
          s.edges = graph.edges.size();
          s.dimension = std::is_same_v<Graph, PoseGraphSE2> ? 2 : 3;
          if (covariance) {
            const Stopwatch time;
            const Covariance computed = [&] {
              try {
                return Covariance(built.problem, covariance_options);
              } catch (const Error& e) {
                throw Error(path.string() + ": " + e.what());
              }
            }();
            for (std::size_t i = 0; i < graph.vertices.size(); ++i) {
              if (built.problem.is_constant(built.vertex_variables[i])) continue;
              s.ids.push_back(graph.vertices[i].id);
              s.blocks.push_back(computed.block(built.vertex_variables[i]));
            }
            s.covariance_s = time.elapsed_s();
          }
          if (out) {
            update_vertices(built, &graph);
            write_g2o(*out, graph);
          }
          return s;
        },
        any);
  });
  py::dict result = summary_dict(solved.summary);
  result["input"] = path.string();
  result["vertices"] = solved.vertices;
  result["edges"] = solved.edges;
  result["dimension"] = solved.dimension;
  if (out) result["output"] = out->string();
  if (covariance) {
    const py::ssize_t d = solved.dimension == 2 ? 3 : 6;
    py::array_t<double> blocks({static_cast<py::ssize_t>(solved.blocks.size()), d, d});
    double* data = blocks.mutable_data();
    for (const Eigen::MatrixXd& block : solved.blocks) {
      for (py::ssize_t r = 0; r < d; ++r) {
        for (py::ssize_t c = 0; c < d; ++c) *data++ = block(r, c);
      }
    }
    result["covariance"] = blocks;
    result["covariance_ids"] = array_from_vector(solved.ids);
    result["covariance_s"] = solved.covariance_s;
  }
  return result;
}

}  // namespace

void bind_solve(py::module_& m) {
  def_checked(
      m, "solve_g2o", &solve_g2o, py::arg("path"), py::arg("max_iterations") = 100,
      py::arg("threads") = 1, py::arg("method") = "lm", py::arg("loss") = "none",
      py::arg("loss_scale") = 1.0, py::arg("ordering") = "auto",
      py::arg("repair_information") = false, py::arg("out") = py::none(),
      py::arg("covariance") = false, py::arg("covariance_gauge") = "error",
      R"(Optimizes a g2o pose graph (VERTEX_SE3:QUAT / EDGE_SE3:QUAT or VERTEX_SE2 / EDGE_SE2).

method: 'lm' or 'gn'; loss: 'none', 'huber' or 'cauchy' (loss_scale in whitened units);
out: write the optimized graph there (atomically; never the input).
covariance: also the covariance of every free vertex at the solution, in carat's tangent
coordinates (3D: xi = [omega, v], T <- T Exp(xi); 2D: [omega, vx, vy]); covariance_gauge:
'error' (a singular H raises carat.Error naming the free vertices) or 'pseudo-inverse'.
Returns a dict: final_cost, initial_cost, iterations, termination, time_s, time_breakdown,
vertices, edges, dimension, ... (the fields of `carat solve-g2o --json`); with covariance also
covariance (N x d x d float64), covariance_ids (the N vertices' g2o ids) and covariance_s.)");
}

}  // namespace carat::python
