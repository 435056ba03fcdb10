#pragma once

/// Residual rows a user writes in numpy: one Python function evaluates any set of whole groups of
/// rows in one call (never one call per row), with one value per variable and the rows asked,
/// and returns the residuals and one Jacobian per variable in tangent columns (or the residuals
/// alone: carat then takes central differences through each manifold, two calls per tangent
/// direction). The GIL is held only around those calls.
///
/// A NumpyRows is what one Problem.add_rows() call adds: G groups of k rows (row r is component
/// r % k of group r / k) over S argument slots. A slot is *shared* (one variable for every group)
/// or *indexed* (a variable per group, e.g. the camera and the point of each BA observation);
/// groups with the same variables form one residual block (numpy_rows_block.hpp). When there are
/// several such blocks, evaluating them one by one would cost a Python call per block, so the
/// batch keeps the last evaluation of all its active groups and serves every block from it while
/// that block's variables hold the same values (see lookup()); an observation's block reads it
/// without the batch's lock (carat/base/read_mostly.hpp). A batch of one block keeps its
/// last whole evaluation the same way (evaluate_all()).
///
/// Jacobians ahead: a cost pass (residuals only) whose point is then linearized costs a second
/// call at the same values. So once the function has returned its Jacobians (not taken by
/// differences), a cost pass also asks for them and keeps them for that linearization: always
/// for a function without the `jacobians` keyword (it computes them anyway), and for one with it
/// while the last cost pass's point was linearized (Levenberg-Marquardt accepting its steps),
/// until Jacobians asked ahead go unused (a rejected step). A cost pass never takes differences.
///
/// Every evaluation reads arrays carat alone holds: returned arrays that anything else still
/// references (a buffer the function fills on every call, a view of one) are copied right after
/// the call. The kept evaluations are dropped when a call into carat begins and ends
/// (PythonProblem), since the data a function reads may change in between.
///
/// The Python function's result is checked (a tuple (r, [J_1, ..., J_S]) or r alone; float64;
/// r of k * n values, J_j of k * n rows by tangent_j columns; a None Jacobian is taken by
/// differences); a failure, or an exception the function raises, is kept in the problem's
/// CallbackErrors (re-raised by the Python call into carat) and thrown to carat as carat::Error
/// naming the rows' name. Non-finite values pass through: carat rejects a trial step there and
/// names the block and row at the start of a solve.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

#include "callback_errors.hpp"
#include "carat/base/read_mostly.hpp"
#include "carat/solver/loss_function.hpp"
#include "carat/solver/residual_block.hpp"
#include "carat/solver/variable_id.hpp"
#include "variable_values.hpp"

namespace carat::python {

namespace py = pybind11;

/// A variable the rows read: its id and where its value lies in the problem's storage.
struct RowsVariable {
  VariableId id;           ///< the problem's variable
  std::size_t offset = 0;  ///< Problem::value_offset(id), doubles
  int ambient = 0;         ///< doubles stored
};

/// One argument of the residual function (after which come the rows).
struct RowsSlot {
  VariableKind kind = VariableKind::kEuclidean;  ///< how its values are shown
  int ambient = 0;                               ///< doubles stored per value
  int tangent = 0;                               ///< columns of its Jacobian
  std::shared_ptr<const Manifold> manifold;      ///< for central differences
  bool indexed = false;                          ///< a variable per group (else `shared`)
  int shared = -1;                               ///< the variable (index into variables) if shared
  std::vector<int> per_group;                    ///< each group's variable if indexed
};

/// A read-only view of rows of numbers in any strided layout: row i (component i % k of group
/// i / k), column c at data + (i / k) * group + (i % k) * component + c * column bytes. Arrays a
/// user builds one coordinate at a time, e.g. J of shape (k, t, n) returned as
/// J.transpose(2, 0, 1), are read in place.
struct StridedRows {
  const char* data = nullptr;    ///< first number
  std::ptrdiff_t group = 0;      ///< bytes between groups (between rows when k == 1)
  std::ptrdiff_t component = 0;  ///< bytes between the rows of a group
  std::ptrdiff_t column = 0;     ///< bytes between columns
  std::size_t group_rows = 1;    ///< k; 1 when rows are evenly spaced (then `group` apart)

  /// Rows of k in a group: evenly spaced rows become one stride.
  static StridedRows make(const char* data, std::ptrdiff_t group, std::ptrdiff_t component,
                          std::ptrdiff_t column, std::size_t k) {
    if (k == 1 || group == static_cast<std::ptrdiff_t>(k) * component) {
      return {data, k == 1 ? group : component, 0, column, 1};
    }
    return {data, group, component, column, k};
  }
  /// Bytes between consecutive rows when they are evenly spaced (group_rows == 1).
  std::ptrdiff_t row_stride() const { return group; }
  /// Where row i starts.
  const char* row(std::size_t i) const {
    return data + (group_rows == 1 ? static_cast<std::ptrdiff_t>(i) * group
                                   : static_cast<std::ptrdiff_t>(i / group_rows) * group +
                                         static_cast<std::ptrdiff_t>(i % group_rows) * component);
  }
  /// Column c of the row starting at `start`.
  double in_row(const char* start, int c) const {
    return *reinterpret_cast<const double*>(start + static_cast<std::ptrdiff_t>(c) * column);
  }
  /// The number at row i, column c.
  double at(std::size_t i, int c = 0) const { return in_row(row(i), c); }
  /// Where row c of the w-th group of k rows starts (no division: for the per-row loops of small
  /// blocks).
  const char* group_row(std::size_t w, std::size_t c, std::size_t k) const {
    return group_rows == 1 ? data + static_cast<std::ptrdiff_t>(w * k + c) * group
                           : data + static_cast<std::ptrdiff_t>(w) * group +
                                 static_cast<std::ptrdiff_t>(c) * component;
  }
};

/// Residuals (and Jacobians) of some whole groups of rows, as the Python function returned them
/// (its arrays are read in place), with each group's loss weight.
class RowsEvaluation {
 public:
  RowsEvaluation() = default;
  RowsEvaluation(const RowsEvaluation&) = delete;
  RowsEvaluation& operator=(const RowsEvaluation&) = delete;
  ~RowsEvaluation();

  /// Rows held (whole groups).
  std::size_t num_rows() const { return num_rows_; }
  /// Whether Jacobians were evaluated.
  bool has_jacobians() const { return !jacobians_.empty(); }
  /// Row i's residual, without the loss weight.
  double residual(std::size_t i) const { return residuals_.at(i); }
  /// Column c of row i of slot j's Jacobian, without the loss weight.
  double jacobian(int j, std::size_t i, int c) const {
    return jacobians_[static_cast<std::size_t>(j)].at(i, c);
  }
  /// The view of slot j's Jacobian.
  const StridedRows& jacobian_view(int j) const { return jacobians_[static_cast<std::size_t>(j)]; }
  /// The view of the residuals.
  const StridedRows& residual_view() const { return residuals_; }
  /// sqrt(rho'(s_g)) of the w-th group held (1 without a group loss).
  double group_weight(std::size_t w) const { return weights_.empty() ? 1.0 : weights_[w]; }
  /// sqrt(rho'(s_g)) of the group of row i (1 without a group loss).
  double weight(std::size_t i) const {
    return weights_.empty() ? 1.0 : weights_[i / static_cast<std::size_t>(group_rows_)];
  }
  /// Row i's share of its group's cost: r_i^2 without a loss, rho(s_g) r_i^2 / s_g with one.
  double cost_share(std::size_t i) const;
  /// Whether a group loss weighted the rows.
  bool weighted() const { return !weights_.empty(); }

 private:
  friend class NumpyRows;
  int group_rows_ = 1;
  std::size_t num_rows_ = 0;
  StridedRows residuals_;
  std::vector<StridedRows> jacobians_;      // one per slot, empty without Jacobians
  std::vector<double> weights_;             // per group: sqrt(rho'(s_g)); empty: no loss
  std::vector<double> rho_, squared_;       // per group: rho(s_g), s_g (with a loss)
  std::vector<std::vector<double>> owned_;  // arrays carat computed (differences)
  py::object keep_;                         // the Python arrays read in place
};

/// The rows of one add_rows() call and the Python function that evaluates them.
class NumpyRows {
 public:
  /// `function` is called as function(*slot_values, rows[, jacobians=bool]) (the keyword when
  /// `pass_jacobians_flag`); `groups` groups of `group_rows` rows; the group loss may be null.
  NumpyRows(py::object function, std::string name, int group_rows, int groups,
            std::vector<RowsSlot> slots, std::vector<RowsVariable> variables,
            std::shared_ptr<const LossFunction> group_loss, std::shared_ptr<CallbackErrors> errors,
            bool pass_jacobians_flag);
  NumpyRows(const NumpyRows&) = delete;
  NumpyRows& operator=(const NumpyRows&) = delete;
  ~NumpyRows();

  /// The name messages give the rows.
  const std::string& name() const { return name_; }
  /// Rows per group (k).
  int group_rows() const { return group_rows_; }
  /// Groups (G).
  int num_groups() const { return groups_; }
  /// Argument slots.
  const std::vector<RowsSlot>& slots() const { return slots_; }
  /// Tangent dimension of each slot.
  std::span<const int> tangent_dims() const { return dims_; }
  /// The variables the slots name.
  const std::vector<RowsVariable>& variables() const { return variables_; }
  /// The loss applied to each group, or null.
  const std::shared_ptr<const LossFunction>& group_loss() const { return group_loss_; }
  /// Whether every group has the same variables (one block, evaluated directly).
  bool single_block() const { return single_block_; }
  /// 0, 1, ..., G - 1 (a single block's groups; empty otherwise).
  std::span<const int> all_groups() const { return all_groups_; }

  /// Evaluates the groups `groups` (ascending, distinct) at `params` (one block's values in slot
  /// order, shared by all those groups); called without the GIL. Throws carat::Error (the
  /// Python exception kept in the CallbackErrors) when the function fails.
  std::shared_ptr<const RowsEvaluation> evaluate(std::span<const int> groups,
                                                 ParameterPointers params, bool jacobians) const;

  /// For the block of a single-block batch (`block_variables`: its variable per slot): every
  /// group at `params`, served from the last whole evaluation while the variables hold the
  /// values it was made at (with Jacobians asked ahead, see above).
  std::shared_ptr<const RowsEvaluation> evaluate_all(std::span<const int> block_variables,
                                                     ParameterPointers params,
                                                     bool jacobians) const;

  /// For a block of a batch of several blocks (`block_variables`: its variable per slot): an
  /// evaluation holding `groups` (ascending) at `params`, and in positions[k] the row where
  /// group groups[k] starts in it. Served from the last evaluation while the block's variables
  /// hold the values it was made at; otherwise, when `params` lie in one array of the problem's
  /// layout (every slot's pointer at its variable's offset from one base, which carat's solver,
  /// evaluation and compression pass), every active group is evaluated at that array's values in
  /// one call and kept; otherwise (e.g. a checker's perturbed copies) `groups` alone at `params`.
  std::shared_ptr<const RowsEvaluation> lookup(std::span<const int> block_variables,
                                               ParameterPointers params,
                                               std::span<const int> groups, bool jacobians,
                                               std::vector<std::size_t>* positions) const;

  /// Where a block's variable lies among the kept values: read once per block and pass, so it
  /// is kept in the block (no look-up through the batch's tables).
  struct HeldSlot {
    std::size_t start = 0;  ///< first double among the kept values
    int ambient = 0;        ///< doubles stored
  };
  /// Where variable v (an index into variables()) lies among the kept values.
  HeldSlot held_slot(int v) const {
    const auto at = static_cast<std::size_t>(v);
    return {variable_start_[at], variables_[at].ambient};
  }

  /// lookup() for a block of one group (`slots`: held_slot() of each of its variables, which are
  /// `block_variables`): calls read(evaluation, w) with an evaluation holding group `group` at
  /// `params` as its w-th group (its rows start at w * group_rows()). The evaluation is valid only
  /// during the call (`read` only reads numbers). A kept evaluation that serves the block is read
  /// without the batch's lock (kept_, a ReadMostly), so that threads reading observations side by
  /// side do not queue for it; a refresh takes the lock.
  template <class Read>
  void read_group(std::span<const HeldSlot> slots, std::span<const int> block_variables,
                  ParameterPointers params, int group, bool jacobians, Read&& read) const {
    const std::span<const int> groups(&group, 1);
    {
      const ReadMostly<Cache>::Read held = kept_.read();
      const Cache* kept = held.get();
      if (kept != nullptr && serves(*kept, held_at(*kept, slots, params, groups), jacobians)) {
        read(*kept->evaluation,
             static_cast<std::size_t>(kept->group_position[static_cast<std::size_t>(group)]));
        return;
      }
    }
    {
      std::lock_guard<std::mutex> lock(cache_mutex_);
      std::size_t w = 0;
      if (const RowsEvaluation* kept =
              kept_group(slots, block_variables, params, group, jacobians, &w)) {
        read(*kept, w);
        return;
      }
    }
    const std::shared_ptr<const RowsEvaluation> own =
        evaluate_groups(groups, Source{params, nullptr}, jacobians);
    read(*own, std::size_t{0});
  }

  /// Drops the kept evaluation (its arrays with it), so that the next request calls the
  /// function (GIL held; no evaluation running).
  void forget() const;

  /// Whether the next cost pass is likely the solve's last (EvaluationHint::likely_final): it
  /// then asks a function with the `jacobians` keyword for no Jacobians ahead, which no
  /// linearization would use.
  void hint_final(bool likely_final) const { likely_final_.store(likely_final); }

  /// Marks `groups` as used by one more block (lookup() evaluates the groups some block uses).
  void acquire(std::span<const int> groups) const;
  /// Undoes acquire().
  void release(std::span<const int> groups) const noexcept;

 private:
  // lookup()'s last evaluation, the values it was made at and where each group lies in it.
  // Immutable once published, but for `linearized`.
  struct Cache {
    std::shared_ptr<const RowsEvaluation> evaluation;
    std::vector<double> values;                // each variable at variable_start_[v]
    std::vector<std::int64_t> group_position;  // each group's index in it, -1: not held
    bool jacobians = false;
    bool ahead = false;                            // Jacobians asked on a cost pass
    mutable std::atomic<bool> linearized = false;  // a request for Jacobians was served from it
  };
  /// Where one evaluation reads its values: one block's parameters (every group the same) or an
  /// array in the problem's layout.
  struct Source {
    ParameterPointers params;
    const double* base = nullptr;
  };
  const double* value(const Source& source, int slot, int group) const;
  /// Evaluates `groups` at `source`; `ahead`: Jacobians asked beyond need (none taken by
  /// differences then).
  std::shared_ptr<const RowsEvaluation> evaluate_groups(std::span<const int> groups,
                                                        const Source& source, bool jacobians,
                                                        bool ahead = false) const;
  /// With the GIL: the arguments, the call, the checks, differences where needed (not `ahead`).
  void call(std::span<const int> groups, const Source& source, bool jacobians, bool ahead,
            RowsEvaluation* out) const;
  py::object invoke(const std::vector<py::object>& arguments, const py::object& rows,
                    bool jacobians) const;
  py::object slot_values(int slot, std::span<const int> groups, const Source& source, int direction,
                         double sign) const;
  StridedRows checked_residuals(const py::handle& r, std::size_t num_rows, py::list* keep) const;
  StridedRows checked_jacobian(const py::handle& J, int slot, std::size_t num_rows,
                               py::list* keep) const;
  [[noreturn]] void fail(const std::string& message) const;
  void apply_loss(RowsEvaluation* evaluation) const;
  /// With the GIL: copies the evaluation's residuals and Jacobians into arrays of its own and
  /// drops the Python ones.
  void own_arrays(RowsEvaluation* evaluation) const;
  const double* common_base(std::span<const int> block_variables, ParameterPointers params) const;
  /// What the cache holds for a request: nothing, the residuals alone, or the Jacobians too.
  enum class Held { kNo, kResidualsOnly, kWithJacobians };
  /// What the cache holds of `groups` (every group when empty) at the block's values
  /// (cache_mutex_ held).
  Held held(std::span<const int> block_variables, ParameterPointers params,
            std::span<const int> groups) const;
  /// held() for the variables whose places among the kept values slot_of(j) gives, j <
  /// num_slots (defined and used in numpy_rows.cpp).
  template <class SlotOf>
  Held held_where(const Cache* kept, std::size_t num_slots, SlotOf slot_of,
                  ParameterPointers params, std::span<const int> groups) const;
  /// held() in `kept` for a block whose variables lie at `slots` among the kept values.
  Held held_at(const Cache& kept, std::span<const HeldSlot> slots, ParameterPointers params,
               std::span<const int> groups) const;
  /// read_group()'s look-up (cache_mutex_ held): the kept evaluation, refreshed first when the
  /// block's values lie in the problem's layout and it does not serve them, and in *w the
  /// group's place in it; null when `params` lie elsewhere.
  const RowsEvaluation* kept_group(std::span<const HeldSlot> slots,
                                   std::span<const int> block_variables, ParameterPointers params,
                                   int group, bool jacobians, std::size_t* w) const;
  /// Whether a request (`jacobians` or not) for what `kept` holds as `state` is served from it;
  /// notes a linearization served.
  static bool serves(const Cache& kept, Held state, bool jacobians) {
    if (state == Held::kWithJacobians) {
      if (jacobians && !kept.linearized.load(std::memory_order_relaxed)) {
        kept.linearized.store(true, std::memory_order_relaxed);
      }
      return true;
    }
    return state == Held::kResidualsOnly && !jacobians;
  }
  /// serves() for the kept evaluation, if any (cache_mutex_ held).
  bool serves(Held state, bool jacobians) const {
    return cache() != nullptr && serves(*cache(), state, jacobians);
  }
  /// Whether an evaluation asked with `jacobians` after a cache miss of `state` asks for the
  /// Jacobians (ahead when not asked); updates the policy (cache_mutex_ held).
  bool ask_jacobians(Held state, bool jacobians) const;
  /// Evaluates every active group at `base` (the problem's layout) into the cache (cache_mutex_
  /// held).
  void refresh_cache(std::span<const int> groups, const double* base, bool jacobians,
                     bool asked) const;

  py::object function_;
  std::string name_;
  int group_rows_ = 1;
  int groups_ = 0;
  std::vector<RowsSlot> slots_;
  std::vector<int> dims_;
  std::vector<RowsVariable> variables_;
  std::shared_ptr<const LossFunction> group_loss_;
  std::shared_ptr<CallbackErrors> errors_;
  bool pass_jacobians_flag_ = false;
  bool single_block_ = true;
  std::vector<int> all_groups_;
  mutable py::object all_rows_;  // 0 .. G k - 1 as a read-only int64 array, made on first use
  mutable std::vector<py::object> spare_;  // per slot: the last values array passed (GIL held)
  mutable std::atomic<bool> jacobians_returned_{false};  // the last Jacobians came from it
  mutable std::atomic<bool> likely_final_{false};        // hint_final()

  /// Makes `fresh` (or nothing) the kept evaluation; the replaced one is freed once no reader
  /// holds it (cache_mutex_ held, or no other thread left: the destructor).
  void publish(std::unique_ptr<Cache> fresh) const { kept_.replace(std::move(fresh)); }
  /// The kept evaluation, or null (cache_mutex_ held).
  const Cache* cache() const { return kept_.current(); }

  mutable bool ahead_ = true;  // cost passes ask for Jacobians (cache_mutex_ held)
  mutable std::mutex cache_mutex_;
  mutable ReadMostly<Cache> kept_;  // replaced under cache_mutex_, read without it
  // Per group: blocks that use it (counts only: a block made during a refresh that misses it
  // asks for its group itself).
  mutable std::vector<std::atomic<int>> users_;
  std::vector<std::size_t> variable_start_;  // where each variable's values lie in Cache::values
  std::size_t values_size_ = 0;              // doubles of Cache::values
};

}  // namespace carat::python
