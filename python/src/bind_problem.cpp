// carat.Problem, carat.solve, carat.compress and carat.solve_recompressed: least-squares problems
// defined from Python, with residual rows written in numpy.
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <optional>
#include <string>

#include "arrays.hpp"
#include "bindings.hpp"
#include "carat/base/error.hpp"
#include "carat/coreset/problem_compression.hpp"
#include "carat/solver/covariance.hpp"
#include "carat/solver/solve.hpp"
#include "integer_arguments.hpp"
#include "mapping_types.hpp"
#include "python_problem.hpp"

namespace carat::python {

namespace {

/// What carat.compress returns: the report, and the problem it can restore.
struct CompressionReport {
  ProblemCompressionReport report;
  PythonProblem* problem = nullptr;
  bool restored = false;
};

/// What carat.covariance returns: marginal covariances of a problem at the values it held.
struct ProblemCovariance {
  std::shared_ptr<const Covariance> covariance;
  const PythonProblem* problem = nullptr;
};

/// cls.def(name, method, extra...) with the method's integer parameters taken as any Python
/// integer and checked by name (integer_arguments.hpp).
template <typename R, typename... A, typename... Extra>
void def_checked_method(py::class_<PythonProblem>& cls, const char* name,
                        R (PythonProblem::*method)(A...), const Extra&... extra) {
  const auto call = [method](PythonProblem& self, A... args) -> R {
    return (self.*method)(std::forward<A>(args)...);
  };
  using W = detail::Wrapper<decltype(call), R(PythonProblem&, A...)>;
  std::vector<std::string> names = detail::argument_names(extra...);
  names.insert(names.begin(), "self");
  cls.def(name, W::wrap(call, std::move(names)), extra...);
}

/// The same for a const method.
template <typename R, typename... A, typename... Extra>
void def_checked_method(py::class_<PythonProblem>& cls, const char* name,
                        R (PythonProblem::*method)(A...) const, const Extra&... extra) {
  const auto call = [method](const PythonProblem& self, A... args) -> R {
    return (self.*method)(std::forward<A>(args)...);
  };
  using W = detail::Wrapper<decltype(call), R(const PythonProblem&, A...)>;
  std::vector<std::string> names = detail::argument_names(extra...);
  names.insert(names.begin(), "self");
  cls.def(name, W::wrap(call, std::move(names)), extra...);
}

/// Solver options from keyword arguments named as SolverOptions' fields (threads for
/// num_threads); TypeError for an unknown one, ValueError for a value out of range.
SolverOptions solver_options(const py::kwargs& kwargs, const char* who) {
  SolverOptions options;
  options.check_blocks = false;
  for (const auto& [key_handle, value] : kwargs) {
    const std::string key = py::str(key_handle);
    try {
      if (key == "max_iterations") {
        options.max_iterations = value.cast<int>();
      } else if (key == "method") {
        options.method = parse_method(value.cast<std::string>());
      } else if (key == "linear_solver") {
        options.linear_solver = parse_linear_solver(value.cast<std::string>());
      } else if (key == "ordering") {
        options.ordering = parse_ordering(value.cast<std::string>());
      } else if (key == "function_tolerance") {
        options.function_tolerance = value.cast<double>();
      } else if (key == "gradient_tolerance") {
        options.gradient_tolerance = value.cast<double>();
      } else if (key == "parameter_tolerance") {
        options.parameter_tolerance = value.cast<double>();
      } else if (key == "initial_trust_region_radius") {
        options.initial_trust_region_radius = value.cast<double>();
      } else if (key == "lm_start") {
        options.lm_start = parse_lm_start(value.cast<std::string>());
      } else if (key == "gauss_newton_phase_radius") {
        options.gauss_newton_phase_radius = value.cast<double>();
      } else if (key == "gauss_newton_phase_min_gain") {
        options.gauss_newton_phase_min_gain = value.cast<double>();
      } else if (key == "max_trust_region_radius") {
        options.max_trust_region_radius = value.cast<double>();
      } else if (key == "max_trust_region_growth") {
        options.max_trust_region_growth = value.cast<double>();
      } else if (key == "min_relative_decrease") {
        options.min_relative_decrease = value.cast<double>();
      } else if (key == "reuse_factorization") {
        options.reuse_factorization = value.cast<bool>();
      } else if (key == "anderson_memory") {
        options.anderson_memory = value.cast<int>();
      } else if (key == "threads") {
        options.num_threads = threads_argument(value.cast<int>());
      } else if (key == "check_blocks") {
        options.check_blocks = value.cast<bool>();
      } else {
        throw py::type_error(std::string(who) + "() got an unexpected keyword argument '" + key +
                             "'");
      }
    } catch (const py::cast_error&) {
      throw py::type_error(std::string(who) + "(): " + key + " has the wrong type (" +
                           std::string(py::str(py::type::of(value).attr("__name__"))) + ")");
    } catch (const Error& e) {
      throw py::value_error(std::string(who) + "(): " + key + ": " + e.what());
    }
  }
  std::string error;
  if (!options.validate(&error)) throw py::value_error(std::string(who) + "(): " + error);
  return options;
}

/// Stops a solve after an iteration once a residual function raised or Ctrl-C was pressed.
IterationCallback stop_on_error(const PythonProblem& problem, InterruptCheck& check) {
  return [&problem, &check](const IterationSummary&) {
    return problem.callback_failed() || check.poll() ? CallbackResult::kAbort
                                                     : CallbackResult::kContinue;
  };
}

SolverSummary solve_problem(PythonProblem& problem, const py::kwargs& kwargs) {
  SolverOptions options = solver_options(kwargs, "solve");
  SolverSummary summary = problem.run([&](Problem& p, InterruptCheck& check) {
    options.iteration_callback = stop_on_error(problem, check);
    options.evaluation_callback = problem.evaluation_hints();
    return solve(options, p);
  });
  if (summary.termination == TerminationType::kFailure) throw Error("solve: " + summary.message);
  return summary;
}

/// `options` with the settings carat.compress and carat.solve_recompressed take.
ProblemCompressionOptions compression_options(int target_rows, int clusters, int min_rows,
                                              std::uint64_t seed, int threads,
                                              ProblemCompressionOptions options = {}) {
  options.compression.target_rows = target_rows;
  options.compression.clusters = clusters;
  options.compression.seed = seed;
  options.min_rows = min_rows;
  options.num_threads = threads_argument(threads);
  return options;
}

RecompressedSolveSummary solve_recompressed_problem(PythonProblem& problem, const std::string& mode,
                                                    int target_rows, int clusters, int min_rows,
                                                    std::uint64_t seed, int max_recompressions,
                                                    bool sampled_start, int sampled_rows_factor,
                                                    double sampled_rows_share, bool exact_forms,
                                                    const py::kwargs& kwargs) {
  RecompressedSolveOptions options;
  options.sampled_start = sampled_start;
  options.sampled_rows_factor = sampled_rows_factor;
  options.sampled_rows_share = sampled_rows_share;
  options.exact_forms = exact_forms;
  options.inner = solver_options(kwargs, "solve_recompressed");
  options.compression = compression_options(target_rows, clusters, min_rows, seed,
                                            options.inner.num_threads, options.compression);
  options.max_recompressions = max_recompressions;
  // The stop tests asked for are also the full problem's between compressions.
  if (kwargs.contains("function_tolerance")) {
    options.function_tolerance = options.inner.function_tolerance;
  }
  if (kwargs.contains("gradient_tolerance")) {
    options.gradient_tolerance = options.inner.gradient_tolerance;
  }
  try {
    options.mode = parse_compression_mode(mode);
  } catch (const Error& e) {
    throw py::value_error(std::string("solve_recompressed(): mode: ") + e.what());
  }
  std::string error;
  if (!options.validate(&error)) throw py::value_error("solve_recompressed(): " + error);
  RecompressedSolveSummary summary = problem.run([&](Problem& p, InterruptCheck& check) {
    options.inner.iteration_callback = stop_on_error(problem, check);
    options.inner.evaluation_callback = problem.evaluation_hints();
    return solve_recompressed(p, options);
  });
  if (summary.termination == TerminationType::kFailure) {
    throw Error("solve_recompressed: " + summary.message);
  }
  return summary;
}

ProblemCovariance covariance_of(PythonProblem& problem, const std::string& gauge,
                                const std::string& linear_solver, int threads) {
  Covariance::Options options;
  try {
    options.gauge = parse_covariance_gauge(gauge);
    options.linear_solver = parse_linear_solver(linear_solver);
  } catch (const Error& e) {
    throw py::value_error(std::string("covariance(): ") + e.what());
  }
  options.num_threads = threads_argument(threads);
  ProblemCovariance out;
  out.problem = &problem;
  out.covariance = problem.run(
      [&](Problem& p, InterruptCheck&) { return std::make_shared<const Covariance>(p, options); });
  return out;
}

py::dict time_breakdown(const TimeBreakdown& t) {
  py::dict out;
  out["linearize_s"] = t.linearize_s;
  out["cost_s"] = t.cost_s;
  out["assembly_s"] = t.assembly_s;
  out["symbolic_s"] = t.symbolic_s;
  out["numeric_s"] = t.numeric_s;
  out["solve_s"] = t.solve_s;
  out["schur_s"] = t.schur_s;
  out["total_s"] = t.total_s;
  return out;
}

}  // namespace

void bind_problem(py::module_& m) {
  py::class_<SolverSummary>(m, "SolverSummary",
                            "What carat.solve did: costs (1/2 sum rho(|r|^2)), iterations, why it "
                            "stopped and where the time went.")
      .def_property_readonly(
          "termination",
          [](const SolverSummary& s) { return std::string(to_string(s.termination)); },
          "'CONVERGENCE', 'NO_CONVERGENCE', 'FAILURE' or 'USER_ABORT'")
      .def_readonly("message", &SolverSummary::message, "why it stopped, in words")
      .def_readonly("initial_cost", &SolverSummary::initial_cost)
      .def_readonly("final_cost", &SolverSummary::final_cost)
      .def_readonly("iterations", &SolverSummary::num_iterations, "iterations run")
      .def_readonly("successful_steps", &SolverSummary::num_successful_steps)
      .def_readonly("unsuccessful_steps", &SolverSummary::num_unsuccessful_steps)
      .def_readonly("num_residual_rows", &SolverSummary::num_residual_rows)
      .def_readonly("num_residual_blocks", &SolverSummary::num_residual_blocks)
      .def_readonly("linear_solver", &SolverSummary::linear_solver)
      .def_property_readonly(
          "time_s", [](const SolverSummary& s) { return s.time.total_s; },
          "wall time of the solve, seconds")
      .def_property_readonly("time_breakdown",
                             [](const SolverSummary& s) { return time_breakdown(s.time); })
      .def("brief_report", &SolverSummary::brief_report)
      .def("full_report", &SolverSummary::full_report,
           "the iteration table and a stage-by-stage breakdown")
      .def("to_dict", &summary_dict, "every field, as `carat solve-g2o --json` prints them")
      .def("__repr__", &SolverSummary::brief_report);

  py::class_<RecompressedSolveSummary>(
      m, "RecompressedSolveSummary",
      "What carat.solve_recompressed did; initial_cost and final_cost are the full problem's.")
      .def_property_readonly(
          "termination",
          [](const RecompressedSolveSummary& s) { return std::string(to_string(s.termination)); })
      .def_readonly("message", &RecompressedSolveSummary::message)
      .def_property_readonly(
          "mode", [](const RecompressedSolveSummary& s) { return std::string(to_string(s.mode)); })
      .def_readonly("switched_to_compression", &RecompressedSolveSummary::switched_to_compression)
      .def_readonly("sampled_start", &RecompressedSolveSummary::sampled_start)
      .def_readonly("sampled_rows", &RecompressedSolveSummary::sampled_rows)
      .def_readonly("sampled_start_cost", &RecompressedSolveSummary::sampled_start_cost)
      .def_readonly(
          "exact_form_blocks", &RecompressedSolveSummary::exact_form_blocks,
          "Blocks the sampled start took in their exact form (registration blocks' lossless rows)")
      .def_readonly("initial_cost", &RecompressedSolveSummary::initial_cost)
      .def_readonly("final_cost", &RecompressedSolveSummary::final_cost)
      .def_readonly("final_gradient_max_norm", &RecompressedSolveSummary::final_gradient_max_norm)
      .def_readonly("compressed_initial_cost", &RecompressedSolveSummary::compressed_initial_cost)
      .def_readonly("compressed_final_cost", &RecompressedSolveSummary::compressed_final_cost)
      .def_readonly("recompressions", &RecompressedSolveSummary::recompressions)
      .def_readonly("inner_iterations", &RecompressedSolveSummary::inner_iterations)
      .def_readonly("full_iterations", &RecompressedSolveSummary::full_iterations)
      .def_property_readonly(
          "iterations",
          [](const RecompressedSolveSummary& s) { return s.inner_iterations + s.full_iterations; })
      .def_readonly("full_rows", &RecompressedSolveSummary::full_rows)
      .def_readonly("compressed_rows", &RecompressedSolveSummary::compressed_rows)
      .def_readonly("compression_s", &RecompressedSolveSummary::compression_s)
      .def_property_readonly("time_s", [](const RecompressedSolveSummary& s) { return s.total_s; })
      .def("brief_report", &RecompressedSolveSummary::brief_report)
      .def("__repr__", &RecompressedSolveSummary::brief_report);

  py::class_<CompressionReport>(m, "CompressionReport",
                                "What carat.compress did; restore() puts the full blocks back.")
      .def_property_readonly("compressed_blocks",
                             [](const CompressionReport& r) { return r.report.compressed_blocks; })
      .def_property_readonly("rows_before",
                             [](const CompressionReport& r) { return r.report.rows_before; })
      .def_property_readonly("rows_after",
                             [](const CompressionReport& r) { return r.report.rows_after; })
      .def_property_readonly("bytes_before",
                             [](const CompressionReport& r) { return r.report.bytes_before; })
      .def_property_readonly("bytes_after",
                             [](const CompressionReport& r) { return r.report.bytes_after; })
      .def_property_readonly("seconds", [](const CompressionReport& r) { return r.report.seconds; })
      .def(
          "restore",
          [](CompressionReport& r) {
            if (r.restored) throw py::value_error("restore: the blocks were restored already");
            r.problem->run([&](Problem& p, InterruptCheck&) { restore_blocks(p, r.report); });
            r.restored = true;
            r.report.replaced.clear();
          },
          "Puts the full blocks back into the problem (at the values it holds now).")
      .def("__repr__", [](const CompressionReport& r) {
        return "CompressionReport(compressed_blocks=" + std::to_string(r.report.compressed_blocks) +
               ", rows_before=" + std::to_string(r.report.rows_before) +
               ", rows_after=" + std::to_string(r.report.rows_after) + ")";
      });

  py::class_<ProblemCovariance>(
      m, "Covariance",
      "Marginal covariances of a problem's free variables at the values it held when "
      "carat.covariance ran, in each variable's tangent coordinates (SE(3): [omega, v] of the "
      "right perturbation T Exp(xi); SE(2): [omega, vx, vy]; Euclidean: its coordinates).")
      .def(
          "block",
          [](const ProblemCovariance& c, int a, const std::optional<int>& b) {
            const VariableId va = c.problem->id(a, "Covariance.block");
            const VariableId vb = b ? c.problem->id(*b, "Covariance.block") : va;
            return c.covariance->block(va, vb);
          },
          py::arg("a"), py::arg("b") = py::none(),
          "The covariance of variable a (tangent x tangent), or the cross-covariance "
          "E[xi_a xi_b^T] of a and b; carat.Error for a constant variable.")
      .def_property_readonly(
          "gauge_dimension",
          [](const ProblemCovariance& c) { return c.covariance->gauge_dimension(); },
          "free directions removed (gauge='pseudo-inverse'); 0 when H is "
          "nonsingular")
      .def_property_readonly(
          "size", [](const ProblemCovariance& c) { return c.covariance->size(); },
          "tangent dimensions of the free variables")
      .def_property_readonly(
          "description", [](const ProblemCovariance& c) { return c.covariance->description(); },
          "the factorization used")
      .def_property_readonly(
          "time_s", [](const ProblemCovariance& c) { return c.covariance->time().total_s; },
          "seconds the computation took");

  py::class_<PythonProblem> problem_class(
      m, "Problem",
      R"(A nonlinear least-squares problem: variables and residual blocks.

Variables are ints. Euclidean values are 1-D arrays, SE(3) poses T_world_body 4 x 4 rigid
transforms (tangent [omega, v], right perturbation T Exp(xi)), SE(2) poses 3 x 3 homogeneous
matrices or [x, y, theta] (tangent [omega, vx, vy]). The cost is 1/2 sum rho(|r|^2).)");
  problem_class.def(py::init<>())
      .def("add_euclidean", &PythonProblem::add_euclidean, py::arg("values"),
           "Adds a Euclidean variable with these initial values (a 1-D array) and returns its id; "
           "a 2-D array adds one per row and returns their ids.")
      .def("add_se3", &PythonProblem::add_se3, py::arg("T_world_body"),
           "Adds an SE(3) variable from a 4 x 4 rigid transform; returns its id.")
      .def("add_se2", &PythonProblem::add_se2, py::arg("T_world_body"),
           "Adds an SE(2) variable from a 3 x 3 homogeneous matrix or [x, y, theta]; returns its "
           "id.")
      .def("set_constant", &PythonProblem::set_constant, py::arg("variables"),
           py::arg("constant") = true, "Holds a variable (or an array of them) fixed, or frees it.")
      .def("set_eliminable", &PythonProblem::set_eliminable, py::arg("variables"),
           py::arg("eliminable") = true,
           "Marks a variable for elimination by the Schur complement (bundle adjustment's "
           "points); no block may connect two eliminable variables.")
      .def("value", &PythonProblem::value, py::arg("variables"),
           "The variable's value: a 1-D array, a 4 x 4 or a 3 x 3 matrix; for an array of "
           "variables of one kind, their values stacked.")
      .def("add_bal_observations", &PythonProblem::add_bal_observations, py::arg("cameras"),
           py::arg("points"), py::arg("observed"), py::kw_only(), py::arg("loss") = "none",
           py::arg("loss_scale") = 1.0,
           "carat's BAL reprojection block for each observation: camera ids (euclidean(9)), point "
           "ids (euclidean(3)), observed pixels (N x 2); returns the block ids.")
      .def_property_readonly("num_variables",
                             [](const PythonProblem& p) { return p.problem().num_variables(); })
      .def_property_readonly(
          "num_residual_blocks",
          [](const PythonProblem& p) { return p.problem().num_residual_blocks(); })
      .def_property_readonly("num_residual_rows", [](const PythonProblem& p) {
        return p.problem().num_residual_rows();
      });

  def_checked_method(problem_class, "is_constant", &PythonProblem::is_constant,
                     py::arg("variable"));
  def_checked_method(problem_class, "set_value", &PythonProblem::set_value, py::arg("variable"),
                     py::arg("value"));
  def_checked_method(problem_class, "add_rows", &PythonProblem::add_rows, py::arg("residual"),
                     py::arg("variables"), py::kw_only(), py::arg("rows"), py::arg("group") = 1,
                     py::arg("loss") = "none", py::arg("loss_scale") = 1.0,
                     py::arg("loss_per") = "group", py::arg("name") = py::none(),
                     R"(Adds `rows` residual rows evaluated by residual(*values, rows).

variables: one entry per argument of `residual`: a variable id (every row reads it), or an
array of rows // group ids (group g reads that variable: a camera and a point per observation).
The function gets one value per argument (an array of one value per group asked for an indexed
argument) and the int64 array of rows asked (whole groups, in order), and returns either
(r, [J_1, ..., J_n]) or r alone: r holds one residual per row asked, J_j one row per row asked
and one column per tangent direction of argument j (None: central differences through the
manifold, two calls per direction). A parameter named `jacobians` receives False on passes
that need residuals only. loss: 'none', 'huber' or 'cauchy' with loss_scale, applied to each
group of `group` rows (loss_per='group', which compresses exactly) or to each residual block
(loss_per='block'). Returns the ids of the residual blocks added, one per distinct tuple of
variables.)");
  def_checked_method(problem_class, "add_relative_pose", &PythonProblem::add_relative_pose,
                     py::arg("i"), py::arg("j"), py::arg("T_i_j"),
                     py::arg("information") = py::none(), py::kw_only(), py::arg("loss") = "none",
                     py::arg("loss_scale") = 1.0,
                     "carat's SE(3) relative-pose block between poses i and j (6 x 6 information, "
                     "translation first); returns its id.");
  def_checked_method(problem_class, "add_relative_pose_se2", &PythonProblem::add_relative_pose_se2,
                     py::arg("i"), py::arg("j"), py::arg("T_i_j"),
                     py::arg("information") = py::none(), py::kw_only(), py::arg("loss") = "none",
                     py::arg("loss_scale") = 1.0,
                     "carat's SE(2) relative-pose block (3 x 3 information in x, y, theta order).");
  def_checked_method(problem_class, "add_pose_prior", &PythonProblem::add_pose_prior,
                     py::arg("variable"), py::arg("T_world_prior"),
                     py::arg("information") = py::none(), py::kw_only(), py::arg("loss") = "none",
                     py::arg("loss_scale") = 1.0,
                     "carat's SE(3) pose prior (6 x 6 information, translation first).");
  def_checked_method(
      problem_class, "add_gicp", &PythonProblem::add_gicp, py::arg("i"), py::arg("j"),
      py::arg("target_means"), py::arg("target_covariances"), py::arg("source_means"),
      py::arg("source_covariances"), py::arg("T_target_source") = py::none(), py::kw_only(),
      py::arg("loss") = "none", py::arg("loss_scale") = 1.0,
      "carat's GICP block between SE(3) poses i (target) and j (source): N correspondences "
      "(means N x 3 in metres, covariances N x 3 x 3), covariances fused at T_target_source "
      "(None: the poses' current relative pose); three rows each. Returns its id.");
  def_checked_method(problem_class, "cost", &PythonProblem::cost, py::arg("threads") = 1,
                     "The cost 1/2 sum rho(|r|^2) at the current values.");
  def_checked_method(problem_class, "gradient", &PythonProblem::gradient, py::arg("threads") = 1,
                     "The gradient over the free variables' tangents, in variable order.");

  m.def("solve", &solve_problem, py::arg("problem"),
        R"(Minimizes the problem's cost from its current values and writes the result back.

Options as keywords: max_iterations (50), method ('lm' or 'gn'), linear_solver ('auto',
'schur', 'cholesky'), ordering, function_tolerance (1e-6), gradient_tolerance (1e-10),
parameter_tolerance (1e-8), initial_trust_region_radius, lm_start ('auto', 'gauss_newton',
'trust_region'), gauss_newton_phase_radius (1e10), gauss_newton_phase_min_gain (0.5),
max_trust_region_radius,
max_trust_region_growth, min_relative_decrease, reuse_factorization, anderson_memory (5),
threads (1), check_blocks (False). Returns a carat.SolverSummary; raises carat.Error when the solve fails
(e.g. a non-finite row at the start, naming the block and row) and re-raises an exception a
residual function raised.)");

  def_checked(
      m, "compress",
      [](PythonProblem& problem, int target_rows, int clusters, int min_rows, std::uint64_t seed,
         int threads) {
        const ProblemCompressionOptions options =
            compression_options(target_rows, clusters, min_rows, seed, threads);
        CompressionReport out;
        out.problem = &problem;
        out.report =
            problem.run([&](Problem& p, InterruptCheck&) { return compress_problem(p, options); });
        return out;
      },
      py::arg("problem"), py::kw_only(), py::arg("target_rows") = 0, py::arg("clusters") = 0,
      py::arg("min_rows") = 0, py::arg("seed") = 1, py::arg("threads") = 1, py::keep_alive<0, 1>(),
      R"(Replaces every block of more than target_rows rows by its exact coreset at the current
values (target_rows 0: the minimum r(r+1)/2 + r + 2). Returns a carat.CompressionReport.)");

  def_checked(
      m, "covariance", &covariance_of, py::arg("problem"), py::kw_only(),
      py::arg("gauge") = "error", py::arg("linear_solver") = "auto", py::arg("threads") = 1,
      py::keep_alive<0, 1>(),
      R"(Marginal covariances of the problem's free variables at its current values (blocks of
(J^T J)^-1, robust losses applied as carat.solve applies them). gauge: 'error' (carat.Error
naming the variables a singular H leaves free) or 'pseudo-inverse'. Returns a
carat.Covariance.)");

  def_checked(m, "solve_recompressed", &solve_recompressed_problem, py::arg("problem"),
              py::kw_only(), py::arg("mode") = "surrogate", py::arg("target_rows") = 0,
              py::arg("clusters") = 0, py::arg("min_rows") = 0, py::arg("seed") = 1,
              py::arg("max_recompressions") = 20, py::arg("sampled_start") = true,
              py::arg("sampled_rows_factor") = 4, py::arg("sampled_rows_share") = 1.0 / 256.0,
              py::arg("exact_forms") = true,
              R"(Solves to the full problem's optimum with compressed blocks.

mode: 'surrogate' (default), 'recompress', 'once' (one compression: fast, not the full optimum),
'auto' or 'full'. 'surrogate' first solves a uniformly sampled problem (sampled_start; per
large block max(sampled_rows_factor x its coreset's minimum, 64, sampled_rows_share of its
rows) rows; with exact_forms, registration blocks enter as their lossless rows instead), then
the full problem from there. Solver options as for carat.solve. Returns a
carat.RecompressedSolveSummary.)");
}

}  // namespace carat::python
