#pragma once

/// carat.Problem: a carat::Problem built from Python (variables given and read back as numpy,
/// residual rows written in numpy, carat's own blocks), with the state a Python call into carat
/// needs: the first exception of a residual function, and a guard against a second call while
/// one runs (carat releases the GIL while it works).

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <memory>
#include <optional>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "callback_errors.hpp"
#include "carat/solver/loss_function.hpp"
#include "carat/solver/problem.hpp"
#include "interrupt.hpp"
#include "numpy_rows.hpp"
#include "variable_values.hpp"

namespace carat::python {

namespace py = pybind11;

/// A problem built from Python; variables are plain ints (their VariableId index).
class PythonProblem {
 public:
  PythonProblem() = default;
  PythonProblem(const PythonProblem&) = delete;
  PythonProblem& operator=(const PythonProblem&) = delete;

  /// A Euclidean variable from a 1-D array of numbers (its id), or one per row of a 2-D array
  /// (an array of ids).
  py::object add_euclidean(const py::handle& values);
  /// An SE(3) variable T_world_body from a 4 x 4 rigid transform.
  int add_se3(const py::handle& T_world_body);
  /// An SE(2) variable from a 3 x 3 homogeneous matrix or [x, y, theta].
  int add_se2(const py::handle& T_world_body);
  /// Holds a variable (an id, or an array of ids) fixed, or frees it.
  void set_constant(const py::handle& variables, bool constant);
  /// Whether the variable is held fixed.
  bool is_constant(int variable) const;
  /// Marks a variable (an id, or an array of ids) for elimination by the Schur complement.
  void set_eliminable(const py::handle& variables, bool eliminable);
  /// The value of a variable as numpy ((n,), 4 x 4 or 3 x 3), or of an array of variables of
  /// one kind stacked ((N, n), N x 4 x 4 or N x 3 x 3).
  py::array_t<double> value(const py::handle& variables) const;
  /// Sets the variable's value (the forms add_* take).
  void set_value(int variable, const py::handle& value);

  /// Problem.add_rows (add_rows.cpp): rows of a numpy residual function; returns the ids of the
  /// residual blocks added (one per distinct tuple of variables).
  py::array_t<int> add_rows(const py::object& function, const py::handle& variables, int rows,
                            int group, const std::string& loss, double loss_scale,
                            const std::string& loss_per, const std::optional<std::string>& name);

  /// RelativePoseBlock between SE(3) variables i and j.
  int add_relative_pose(int i, int j, const py::handle& T_i_j, const py::handle& information,
                        const std::string& loss, double loss_scale);
  /// RelativePoseSE2Block between SE(2) variables i and j.
  int add_relative_pose_se2(int i, int j, const py::handle& T_i_j, const py::handle& information,
                            const std::string& loss, double loss_scale);
  /// PosePriorBlock on an SE(3) variable.
  int add_pose_prior(int variable, const py::handle& T_world_prior, const py::handle& information,
                     const std::string& loss, double loss_scale);
  /// One GicpBlock between SE(3) variables i (target) and j (source) over N correspondences:
  /// target and source means (N x 3, metres) and covariances (N x 3 x 3); the covariances are
  /// fused at T_target_source (None: the current T_world_i^-1 T_world_j).
  int add_gicp(int i, int j, const py::handle& target_means, const py::handle& target_covariances,
               const py::handle& source_means, const py::handle& source_covariances,
               const py::handle& T_target_source, const std::string& loss, double loss_scale);
  /// One SnavelyReprojectionBlock per observation (BAL cameras of 9 numbers, points of 3).
  py::array_t<int> add_bal_observations(const py::handle& cameras, const py::handle& points,
                                        const py::handle& observed, const std::string& loss,
                                        double loss_scale);

  /// The cost 1/2 sum rho(|r|^2) at the current values.
  double cost(int threads);
  /// The gradient over the free variables' tangents, in variable order.
  py::array_t<double> gradient(int threads);

  /// The C++ problem (read-only).
  const Problem& problem() const { return problem_; }

  /// Runs f(problem, check) with the GIL released (interrupt.hpp), as the one call into carat
  /// on this problem: raises RuntimeError when another is running, and re-raises the first
  /// exception a residual function raised meanwhile (its traceback included) in place of what
  /// carat made of it.
  template <typename F>
  auto run(F&& f) {
    Guard guard(*this);
    errors_->clear();
    try {
      if constexpr (std::is_void_v<std::invoke_result_t<F, Problem&, InterruptCheck&>>) {
        run_released([&](InterruptCheck& check) { f(problem_, check); });
        errors_->raise_if_failed();
      } else {
        auto result = run_released([&](InterruptCheck& check) { return f(problem_, check); });
        errors_->raise_if_failed();
        return result;
      }
    } catch (const py::error_already_set&) {
      throw;
    } catch (...) {
      errors_->raise_if_failed();
      throw;
    }
  }

  /// The id of `variable`; ValueError naming `what` when there is no such variable.
  VariableId id(int variable, const std::string& what) const;

  /// Whether a residual function has raised during the running call (any thread).
  bool callback_failed() const { return errors_->failed(); }

  /// Tells every batch of add_rows() what each pass of a solve is for (SolverOptions::
  /// evaluation_callback): a cost pass the solve will likely end after asks no Jacobians ahead.
  EvaluationCallback evaluation_hints() const;

 private:
  /// The one running call: marks the problem busy, and forgets every batch's kept evaluation
  /// when the call begins and ends (the data a residual function reads may change between
  /// calls; an evaluation kept after a call would also hold its arrays).
  struct Guard {
    explicit Guard(PythonProblem& p);
    ~Guard();
    PythonProblem& problem;
  };
  friend struct Guard;

  /// The ids of an int or a 1-D array of ints (checked); *scalar says which it was.
  std::vector<VariableId> ids(const py::handle& variables, const std::string& what,
                              bool* scalar = nullptr) const;
  /// The kind of `variable`.
  VariableKind kind(VariableId v) const;
  /// Throws ValueError unless the problem is free (no call into carat is running).
  void check_free() const;

  /// Forgets every batch's kept evaluation (GIL held).
  void forget_evaluations();

  Problem problem_;
  std::shared_ptr<CallbackErrors> errors_ = std::make_shared<CallbackErrors>();
  std::vector<std::weak_ptr<const NumpyRows>> batches_;  // of add_rows(), for forget_evaluations()
  bool busy_ = false;
};

/// The loss named `name` ("none", "huber", "cauchy") with `scale`; ValueError naming `what`.
std::shared_ptr<const LossFunction> loss_argument(const std::string& name, double scale,
                                                  const std::string& what);

}  // namespace carat::python
