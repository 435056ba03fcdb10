// carat.coreset: the exact quadratic coreset of least-squares rows, from numpy.
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <Eigen/Core>
#include <optional>
#include <string>

#include "arrays.hpp"
#include "bindings.hpp"
#include "carat/base/machine_memory.hpp"
#include "carat/coreset/row_coreset.hpp"
#include "carat/coreset/row_coreset_cost.hpp"
#include "integer_arguments.hpp"
#include "interrupt.hpp"

namespace carat::python {

namespace {

using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// Most Jacobian columns the binding accepts: D = 128 lifts rows to 8,384 numbers.
constexpr py::ssize_t kMaxColumns = 128;
/// Floating-point operations per second assumed for the work estimate (as carat coreset-check).
constexpr double kOperationsPerSecond = 2e9;
/// Longest call the binding starts, seconds (as carat coreset-check).
constexpr double kMaxSeconds = 600.0;

/// Refuses, before any work, a coreset this machine cannot hold (the rows it lifts, L numbers
/// each, included) or one that would run for more than ten minutes: ValueError naming J.
void check_cost(py::ssize_t n, py::ssize_t columns, const RowCoresetOptions& options) {
  const RowCoresetCost cost =
      estimate_row_coreset(static_cast<long>(n), static_cast<int>(columns), options);
  const std::string shape = std::to_string(n) + " x " + std::to_string(columns);
  const auto available = static_cast<double>(available_memory_bytes());
  if (cost.bytes > 0.8 * available) {
    throw py::value_error("J: the coreset of " + shape + " rows needs about " +
                          format_bytes(cost.bytes) + " of memory (" +
                          std::to_string(cost.lifted_rows) + " rows lifted to " +
                          std::to_string(cost.lifted_dim) + " numbers each); " +
                          format_bytes(available) + " are available");
  }
  const double seconds = cost.operations / kOperationsPerSecond;
  if (seconds > kMaxSeconds) {
    throw py::value_error(
        "J: the coreset of " + shape + " rows would take about " +
        std::to_string(static_cast<long>(seconds / 60.0)) + " minutes (" +
        std::to_string(static_cast<long>(cost.levels)) + " levels, each an elimination of " +
        std::to_string(cost.clusters) + " points in " + std::to_string(cost.lifted_dim) +
        " dimensions); use more clusters (e.g. " + std::to_string(2 * (cost.lifted_dim + 1)) +
        "), fewer rows or fewer columns (a reduced Jacobian)");
  }
}

/// "(2, 3)": an array's shape as numpy prints it.
std::string shape_text(const py::array& a) {
  std::string out = "(";
  for (py::ssize_t d = 0; d < a.ndim(); ++d) out += (d ? ", " : "") + std::to_string(a.shape(d));
  return out + (a.ndim() == 1 ? ",)" : ")");
}

py::tuple coreset(const py::handle& J_in, const py::handle& e_in, std::optional<int> target,
                  std::optional<int> clusters, std::uint64_t seed) {
  const auto J = as_float64(J_in, "J");
  const auto e = as_float64(e_in, "e");
  if (J.ndim() != 2 || J.shape(1) < 1) {
    throw py::value_error("J: expected an N x D array of Jacobian rows (D >= 1), got shape " +
                          shape_text(J));
  }
  if (J.shape(1) > kMaxColumns) {
    throw py::value_error("J: at most " + std::to_string(kMaxColumns) + " columns (the lifted " +
                          "dimension grows as D^2 / 2), got " + std::to_string(J.shape(1)));
  }
  const py::ssize_t n = J.shape(0);
  const bool column = e.ndim() == 2 && e.shape(1) == 1;
  if (!(e.ndim() == 1 || column) || e.shape(0) != n) {
    throw py::value_error("e: expected " + std::to_string(n) +
                          " residuals (one per row of J), got shape " + shape_text(e));
  }
  if (n == 0) throw py::value_error("J: no rows");
  RowCoresetOptions options;
  if (target) {
    if (*target < 1) throw py::value_error("target: must be >= 1, got " + std::to_string(*target));
    options.target_rows = *target;
  }
  if (clusters) {
    if (*clusters < 0) {
      throw py::value_error("clusters: must be >= 0 (0: the default), got " +
                            std::to_string(*clusters));
    }
    options.clusters = *clusters;
  }
  options.seed = seed;
  check_cost(n, J.shape(1), options);
  const Eigen::Map<const RowMajor> J_map(J.data(), n, J.shape(1));
  const Eigen::Map<const Eigen::VectorXd> e_map(e.data(), n);
  RowCoreset result =
      run_released([&](InterruptCheck&) { return select_coreset_rows(J_map, e_map, options); });
  py::array_t<std::int64_t> indices(static_cast<py::ssize_t>(result.rows.size()));
  std::copy(result.rows.begin(), result.rows.end(), indices.mutable_data());
  return py::make_tuple(indices, array_from_vector(result.weights));
}

}  // namespace

void bind_coreset(py::module_& m) {
  def_checked(m, "coreset", &coreset, py::arg("J"), py::arg("e"), py::arg("target") = py::none(),
              py::arg("clusters") = py::none(), py::arg("seed") = 0,
              R"(Exact quadratic coreset of least-squares rows.

Selects M rows k of J (N x D) and e (N) with weights w_k > 0 such that
sum w_k J_k^T J_k = J^T J, sum w_k J_k^T e_k = J^T e and sum w_k e_k^2 = e^T e
to rounding (Fast-Caratheodory, time linear in N).

target: M, at least D(D+1)/2 + D + 2 (None: that minimum, 29 for D = 6).
clusters: clusters per level (None or 0: max(64, 2(L + 1)), L = D(D+1)/2 + D + 1).
J has at most 128 columns; a size whose coreset would not fit the memory available (the rows
it lifts to D(D+1)/2 + D + 1 numbers each included) or would take more than ten minutes is
refused before any work (ValueError). Ctrl-C ends the call between levels and eliminations.
seed: seed of the row shuffle.
Returns (indices, weights): ascending row indices (int64) and their weights. N <= M returns
every row with weight 1. J and e are used in place when they are C-contiguous float64.
Raises carat.Error for a non-finite row (naming it) or a target below the minimum.)");
  def_checked(
      m, "minimum_coreset_rows",
      [](int columns) {
        if (columns < 1 || columns > kMaxColumns) {
          throw py::value_error("columns: must be in [1, " + std::to_string(kMaxColumns) +
                                "], got " + std::to_string(columns));
        }
        return minimum_coreset_rows(columns);
      },
      py::arg("columns"), "Smallest coreset target for D Jacobian columns: D(D+1)/2 + D + 2.");
}

}  // namespace carat::python
