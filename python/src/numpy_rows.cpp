#include "numpy_rows.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numeric>
#include <utility>

#include "carat/base/error.hpp"

namespace carat::python {

namespace {

std::string shape_text(const py::array& a) {
  std::string out = "(";
  for (py::ssize_t d = 0; d < a.ndim(); ++d) {
    out += (d ? ", " : "") + std::to_string(a.shape(d));
  }
  return out + (a.ndim() == 1 ? ",)" : ")");
}

/// Drops a Python reference with the GIL (or leaks it once the interpreter is gone).
void drop(py::object& object) {
  if (!object) return;
  if (!Py_IsInitialized()) {
    (void)object.release();
    return;
  }
  py::gil_scoped_acquire gil;
  object = py::object();
}

/// Whether every array in `kept` is held by carat alone: referenced once (by the list), and so is
/// each array it is a view of, down to the one that owns the numbers. Nothing else can then
/// write them (GIL held).
bool held_alone(const py::object& kept) {
  for (const py::handle item : py::reinterpret_borrow<py::list>(kept)) {
    PyObject* object = item.ptr();
    while (true) {
      if (Py_REFCNT(object) != 1 || !py::isinstance<py::array>(object)) return false;
      PyObject* base = py::detail::array_proxy(object)->base;
      if (base == nullptr) {
        if ((py::detail::array_proxy(object)->flags & py::detail::npy_api::NPY_ARRAY_OWNDATA_) ==
            0) {
          return false;
        }
        break;
      }
      object = base;
    }
  }
  return true;
}

/// Copies `rows` rows of `columns` numbers from `view` into a new array of `owned` and points
/// `view` at it (row after row, contiguous).
void copy_into(StridedRows* view, std::size_t rows, std::size_t columns,
               std::vector<std::vector<double>>* owned) {
  std::vector<double>& copy = owned->emplace_back(rows * columns);
  for (std::size_t i = 0; i < rows; ++i) {
    const char* row = view->row(i);
    for (std::size_t c = 0; c < columns; ++c) {
      copy[i * columns + c] = view->in_row(row, static_cast<int>(c));
    }
  }
  *view = StridedRows::make(reinterpret_cast<const char*>(copy.data()),
                            static_cast<std::ptrdiff_t>(columns * sizeof(double)), 0,
                            sizeof(double), 1);
}

}  // namespace

RowsEvaluation::~RowsEvaluation() { drop(keep_); }

double RowsEvaluation::cost_share(std::size_t i) const {
  const double r = residuals_.at(i);
  if (weights_.empty()) return r * r;
  const std::size_t g = i / static_cast<std::size_t>(group_rows_);
  const double s = squared_[g];
  return s > 0.0 ? rho_[g] * (r * r) / s : 0.0;
}

NumpyRows::NumpyRows(py::object function, std::string name, int group_rows, int groups,
                     std::vector<RowsSlot> slots, std::vector<RowsVariable> variables,
                     std::shared_ptr<const LossFunction> group_loss,
                     std::shared_ptr<CallbackErrors> errors, bool pass_jacobians_flag)
    : function_(std::move(function)),
      name_(std::move(name)),
      group_rows_(group_rows),
      groups_(groups),
      slots_(std::move(slots)),
      variables_(std::move(variables)),
      group_loss_(std::move(group_loss)),
      errors_(std::move(errors)),
      pass_jacobians_flag_(pass_jacobians_flag) {
  spare_.resize(slots_.size());
  for (const RowsSlot& slot : slots_) {
    dims_.push_back(slot.tangent);
    if (!slot.indexed) continue;
    for (int v : slot.per_group) {
      if (v != slot.per_group.front()) single_block_ = false;
    }
  }
  std::size_t start = 0;
  for (const RowsVariable& v : variables_) {
    variable_start_.push_back(start);
    start += static_cast<std::size_t>(v.ambient);
  }
  values_size_ = start;
  if (single_block_) {
    all_groups_.resize(static_cast<std::size_t>(groups_));
    std::iota(all_groups_.begin(), all_groups_.end(), 0);
  } else {
    users_ = std::vector<std::atomic<int>>(static_cast<std::size_t>(groups_));
    kept_.enable_reads();  // observations' blocks read the kept evaluation without the lock
  }
}

NumpyRows::~NumpyRows() {
  publish(nullptr);
  for (py::object& spare : spare_) drop(spare);
  drop(all_rows_);
  drop(function_);
}

const double* NumpyRows::value(const Source& source, int slot, int group) const {
  if (!source.base) return source.params[static_cast<std::size_t>(slot)];
  const RowsSlot& s = slots_[static_cast<std::size_t>(slot)];
  const int v = s.indexed ? s.per_group[static_cast<std::size_t>(group)] : s.shared;
  return source.base + variables_[static_cast<std::size_t>(v)].offset;
}

void NumpyRows::fail(const std::string& message) const {
  errors_->record(PyExc_ValueError, message);
  throw Error(message);
}

py::object NumpyRows::slot_values(int slot, std::span<const int> groups, const Source& source,
                                  int direction, double sign) const {
  const RowsSlot& s = slots_[static_cast<std::size_t>(slot)];
  std::vector<py::ssize_t> shape = value_shape(s.kind, s.ambient);
  const auto size = static_cast<std::size_t>(value_size(s.kind, s.ambient));
  std::vector<double> moved(static_cast<std::size_t>(s.ambient));
  std::vector<double> delta(static_cast<std::size_t>(s.tangent), 0.0);
  const auto write = [&](int group, double* out) {
    const double* x = value(source, slot, group);
    if (direction < 0) {
      write_value(s.kind, s.ambient, x, out);
      return;
    }
    const auto d = static_cast<std::size_t>(direction);
    delta[d] = sign * difference_step(s.kind, s.ambient, x, direction);
    s.manifold->plus(x, delta.data(), moved.data());
    write_value(s.kind, s.ambient, moved.data(), out);
  };
  if (!s.indexed) {
    py::array_t<double> out(shape);
    write(groups.front(), out.mutable_data());
    return out;
  }
  // One value per group, column-major: values[:, e] of every group is contiguous, which is how
  // whole-array numpy code reads it.
  const auto count = static_cast<py::ssize_t>(groups.size());
  shape.insert(shape.begin(), count);
  using ValuesArray = py::array_t<double, py::array::f_style>;
  // The previous call's array of this slot, when nothing else holds it any more (the user's
  // function kept neither it nor a view of it) and it has this shape: refilled instead of a new
  // one, whose fresh pages would each cost a page fault.
  py::object& spare = spare_[static_cast<std::size_t>(slot)];
  bool reuse = direction < 0 && spare && spare.ref_count() == 1;
  if (reuse) {
    const auto held = py::reinterpret_borrow<ValuesArray>(spare);
    reuse = held.ndim() == static_cast<py::ssize_t>(shape.size()) && held.writeable();
    for (std::size_t d = 0; reuse && d < shape.size(); ++d) {
      reuse = held.shape(static_cast<py::ssize_t>(d)) == shape[d];
    }
  }
  ValuesArray out = reuse ? py::reinterpret_borrow<ValuesArray>(spare) : ValuesArray(shape);
  if (direction < 0) spare = out;
  double* data = out.mutable_data();
  if (s.kind == VariableKind::kEuclidean && direction < 0) {  // the stored numbers themselves
    const auto n = static_cast<std::size_t>(count);
    for (std::size_t k = 0; k < n; ++k) {
      const double* x = value(source, slot, groups[k]);
      for (std::size_t e = 0; e < size; ++e) data[k + n * e] = x[e];
    }
    return out;
  }
  std::vector<double> one(size);
  const bool matrix = shape.size() == 3;
  const auto columns = matrix ? static_cast<std::size_t>(shape[2]) : size;
  const auto rows_per_value = matrix ? static_cast<std::size_t>(shape[1]) : 1;
  const auto n = static_cast<std::size_t>(count);
  for (std::size_t k = 0; k < n; ++k) {
    write(groups[k], one.data());
    // (k, r, c) lies at k + n (r + rows c); a vector's element e at k + n e.
    for (std::size_t r = 0; r < rows_per_value; ++r) {
      for (std::size_t c = 0; c < columns; ++c) {
        data[k + n * (r + rows_per_value * c)] = one[r * columns + c];
      }
    }
  }
  return out;
}

py::object NumpyRows::invoke(const std::vector<py::object>& arguments, const py::object& rows,
                             bool jacobians) const {
  py::tuple args(arguments.size() + 1);
  for (std::size_t j = 0; j < arguments.size(); ++j) args[j] = arguments[j];
  args[arguments.size()] = rows;
  try {
    if (pass_jacobians_flag_) {
      py::dict kwargs;
      kwargs["jacobians"] = jacobians;
      return function_(*args, **kwargs);
    }
    return function_(*args);
  } catch (py::error_already_set& e) {
    errors_->record(e);
    throw Error(name_ + ": its residual function raised " +
                std::string(py::str(e.type().attr("__name__"))) + ": " +
                std::string(py::str(e.value())));
  }
}

StridedRows NumpyRows::checked_residuals(const py::handle& r, std::size_t num_rows,
                                         py::list* keep) const {
  py::array a;
  try {
    a = py::module_::import("numpy").attr("asarray")(r);
  } catch (py::error_already_set&) {
  }
  if (!a) {
    fail(name_ + ": the residual function returned " +
         std::string(py::str(py::type::of(r).attr("__name__"))) +
         " for the residuals; expected a float64 array");
  }
  if (a.dtype().kind() != 'f' || a.itemsize() != 8) {
    fail(name_ + ": the residual function returned residuals of dtype " +
         std::string(py::str(a.dtype())) + "; expected float64");
  }
  const auto n = static_cast<py::ssize_t>(num_rows);
  const auto k = static_cast<py::ssize_t>(group_rows_);
  const bool flat = a.ndim() == 1 && a.shape(0) == n;
  const bool grouped = a.ndim() == 2 && a.shape(0) * k == n && a.shape(1) == k;
  if (!flat && !grouped) {
    fail(name_ + ": the residual function returned residuals of shape " + shape_text(a) +
         "; expected (" + std::to_string(n) + ",), one per row asked" +
         (k > 1 ? " (or (" + std::to_string(n / k) + ", " + std::to_string(k) + "))" : ""));
  }
  keep->append(a);
  const auto* data = static_cast<const char*>(a.data());
  return flat ? StridedRows::make(data, a.strides(0), 0, 0, 1)
              : StridedRows::make(data, a.strides(0), a.strides(1), 0, static_cast<std::size_t>(k));
}

StridedRows NumpyRows::checked_jacobian(const py::handle& J, int slot, std::size_t num_rows,
                                        py::list* keep) const {
  const RowsSlot& s = slots_[static_cast<std::size_t>(slot)];
  const std::string which = "the Jacobian of argument " + std::to_string(slot + 1) + " (" +
                            describe(s.kind, s.ambient) + ")";
  py::array a;
  try {
    a = py::module_::import("numpy").attr("asarray")(J);
  } catch (py::error_already_set&) {
  }
  if (!a) {
    fail(name_ + ": the residual function returned " +
         std::string(py::str(py::type::of(J).attr("__name__"))) + " for " + which +
         "; expected a float64 array");
  }
  if (a.dtype().kind() != 'f' || a.itemsize() != 8) {
    fail(name_ + ": the residual function returned " + which + " of dtype " +
         std::string(py::str(a.dtype())) + "; expected float64");
  }
  const auto n = static_cast<py::ssize_t>(num_rows);
  const auto k = static_cast<py::ssize_t>(group_rows_);
  const auto t = static_cast<py::ssize_t>(s.tangent);
  const bool plain = a.ndim() == 2 && a.shape(0) == n && a.shape(1) == t;
  const bool grouped = a.ndim() == 3 && a.shape(0) * k == n && a.shape(1) == k && a.shape(2) == t;
  const bool column = t == 1 && a.ndim() == 1 && a.shape(0) == n;
  if (!plain && !grouped && !column) {
    fail(name_ + ": the residual function returned " + which + " of shape " + shape_text(a) +
         "; expected (" + std::to_string(n) + ", " + std::to_string(t) +
         "), a row per row asked and a column per tangent direction");
  }
  keep->append(a);
  const auto* data = static_cast<const char*>(a.data());
  if (column) return StridedRows::make(data, a.strides(0), 0, 0, 1);
  if (plain) return StridedRows::make(data, a.strides(0), 0, a.strides(1), 1);
  return StridedRows::make(data, a.strides(0), a.strides(1), a.strides(2),
                           static_cast<std::size_t>(k));
}

void NumpyRows::call(std::span<const int> groups, const Source& source, bool jacobians, bool ahead,
                     RowsEvaluation* out) const {
  if (errors_->failed()) {
    throw Error(name_ + ": not evaluated after an earlier error of a residual function");
  }
  const std::size_t k = static_cast<std::size_t>(group_rows_);
  const std::size_t n = groups.size() * k;
  py::object rows;
  if (groups.size() == static_cast<std::size_t>(groups_)) {  // ascending and distinct: all
    if (!all_rows_) {
      py::array_t<std::int64_t> all(static_cast<py::ssize_t>(n));
      std::iota(all.mutable_data(), all.mutable_data() + n, std::int64_t{0});
      all.attr("setflags")(py::arg("write") = false);
      all_rows_ = std::move(all);
    }
    rows = all_rows_;
  } else {
    py::array_t<std::int64_t> some(static_cast<py::ssize_t>(n));
    std::int64_t* data = some.mutable_data();
    for (std::size_t g = 0; g < groups.size(); ++g) {
      for (std::size_t c = 0; c < k; ++c) {
        data[g * k + c] = static_cast<std::int64_t>(groups[g]) * static_cast<std::int64_t>(k) +
                          static_cast<std::int64_t>(c);
      }
    }
    rows = std::move(some);
  }
  const std::size_t num_slots = slots_.size();
  std::vector<py::object> arguments(num_slots);
  for (std::size_t j = 0; j < num_slots; ++j) {
    arguments[j] = slot_values(static_cast<int>(j), groups, source, -1, 0.0);
  }
  const py::object result = invoke(arguments, rows, jacobians);
  py::object r = result;
  py::object J = py::none();
  if (py::isinstance<py::tuple>(result) && py::len(result) == 2) {
    r = result[py::int_(0)];
    J = result[py::int_(1)];
  }
  py::list keep;
  out->residuals_ = checked_residuals(r, n, &keep);
  if (jacobians) {
    std::vector<py::object> given(num_slots, py::none());
    if (py::isinstance<py::list>(J) || py::isinstance<py::tuple>(J)) {
      if (py::len(J) != num_slots) {
        fail(name_ + ": the residual function returned " + std::to_string(py::len(J)) +
             " Jacobians for " + std::to_string(num_slots) +
             " variables; expected one per variable (None: central differences)");
      }
      for (std::size_t j = 0; j < num_slots; ++j) given[j] = J[py::int_(j)];
    } else if (!J.is_none()) {
      if (num_slots != 1) {
        fail(name_ + ": the residual function returned one Jacobian for " +
             std::to_string(num_slots) + " variables; expected a list with one per variable");
      }
      given[0] = J;
    }
    out->jacobians_.resize(num_slots);
    bool differences = false;
    for (std::size_t j = 0; j < num_slots; ++j) {
      if (given[j].is_none()) {
        differences = true;
      } else {
        out->jacobians_[j] = checked_jacobian(given[j], static_cast<int>(j), n, &keep);
      }
    }
    jacobians_returned_ = !differences;
    if (differences && ahead) {  // not worth two calls per direction: the residuals alone
      out->jacobians_.clear();
    } else if (differences) {
      // The residuals and the Jacobians given are copied first: the function may fill the same
      // arrays on every call.
      copy_into(&out->residuals_, n, 1, &out->owned_);
      for (std::size_t j = 0; j < num_slots; ++j) {
        if (given[j].is_none()) continue;
        copy_into(&out->jacobians_[j], n, static_cast<std::size_t>(slots_[j].tangent),
                  &out->owned_);
      }
      for (std::size_t j = 0; j < num_slots; ++j) {
        if (!given[j].is_none()) continue;
        const RowsSlot& s = slots_[j];
        const auto t = static_cast<std::size_t>(s.tangent);
        std::vector<double>& columns = out->owned_.emplace_back(n * t);
        std::vector<double> steps(groups.size());
        std::vector<py::object> moved = arguments;
        for (std::size_t d = 0; d < t; ++d) {
          py::list scratch;
          moved[j] = slot_values(static_cast<int>(j), groups, source, static_cast<int>(d), 1.0);
          const StridedRows plus = checked_residuals(invoke(moved, rows, false), n, &scratch);
          std::vector<double> plus_values(n);
          for (std::size_t i = 0; i < n; ++i) plus_values[i] = plus.at(i);
          moved[j] = slot_values(static_cast<int>(j), groups, source, static_cast<int>(d), -1.0);
          const StridedRows minus = checked_residuals(invoke(moved, rows, false), n, &scratch);
          for (std::size_t g = 0; g < groups.size(); ++g) {
            const double h =
                difference_step(s.kind, s.ambient, value(source, static_cast<int>(j), groups[g]),
                                static_cast<int>(d));
            for (std::size_t c = 0; c < k; ++c) {
              const std::size_t i = g * k + c;
              columns[i * t + d] = (plus_values[i] - minus.at(i)) / (2.0 * h);
            }
          }
        }
        out->jacobians_[j] = StridedRows::make(reinterpret_cast<const char*>(columns.data()),
                                               static_cast<std::ptrdiff_t>(t * sizeof(double)), 0,
                                               sizeof(double), 1);
      }
    }
  }
  out->keep_ = std::move(keep);
}

void NumpyRows::apply_loss(RowsEvaluation* evaluation) const {
  if (!group_loss_) return;
  const std::size_t k = static_cast<std::size_t>(group_rows_);
  const std::size_t groups = evaluation->num_rows_ / k;
  evaluation->weights_.resize(groups);
  evaluation->rho_.resize(groups);
  evaluation->squared_.resize(groups);
  for (std::size_t g = 0; g < groups; ++g) {
    double s = 0.0;
    for (std::size_t c = 0; c < k; ++c) {
      const double r = evaluation->residuals_.at(g * k + c);
      s += r * r;
    }
    const LossValue value = group_loss_->evaluate(s);
    if (std::isfinite(s) &&
        !(std::isfinite(value.rho) && std::isfinite(value.rho1) && value.rho1 >= 0.0)) {
      throw Error(name_ + ": the group loss '" + group_loss_->name() +
                  "' returned rho = " + std::to_string(value.rho) +
                  ", rho' = " + std::to_string(value.rho1) + " at s = " + std::to_string(s));
    }
    evaluation->weights_[g] = std::sqrt(value.rho1);
    evaluation->rho_[g] = value.rho;
    evaluation->squared_[g] = s;
  }
}

void NumpyRows::own_arrays(RowsEvaluation* evaluation) const {
  const std::size_t n = evaluation->num_rows_;
  copy_into(&evaluation->residuals_, n, 1, &evaluation->owned_);
  for (std::size_t j = 0; j < evaluation->jacobians_.size(); ++j) {
    copy_into(&evaluation->jacobians_[j], n, static_cast<std::size_t>(dims_[j]),
              &evaluation->owned_);
  }
  evaluation->keep_ = py::object();
}

std::shared_ptr<const RowsEvaluation> NumpyRows::evaluate_groups(std::span<const int> groups,
                                                                 const Source& source,
                                                                 bool jacobians, bool ahead) const {
  auto out = std::make_shared<RowsEvaluation>();
  out->group_rows_ = group_rows_;
  out->num_rows_ = groups.size() * static_cast<std::size_t>(group_rows_);
  {
    py::gil_scoped_acquire gil;
    call(groups, source, jacobians, ahead, out.get());
    // Arrays something else holds (a buffer the function fills on every call, a view of one)
    // could be written again before carat reads them, by the next call or by the user: copied.
    if (!held_alone(out->keep_)) own_arrays(out.get());
  }
  apply_loss(out.get());
  return out;
}

std::shared_ptr<const RowsEvaluation> NumpyRows::evaluate(std::span<const int> groups,
                                                          ParameterPointers params,
                                                          bool jacobians) const {
  return evaluate_groups(groups, Source{params, nullptr}, jacobians);
}

const double* NumpyRows::common_base(std::span<const int> block_variables,
                                     ParameterPointers params) const {
  if (block_variables.size() < 2) return nullptr;  // one pointer proves nothing
  const auto base_of = [&](std::size_t j) {
    return reinterpret_cast<std::uintptr_t>(params[j]) -
           variables_[static_cast<std::size_t>(block_variables[j])].offset * sizeof(double);
  };
  const std::uintptr_t base = base_of(0);
  for (std::size_t j = 1; j < block_variables.size(); ++j) {
    if (base_of(j) != base) return nullptr;
  }
  return reinterpret_cast<const double*>(base);
}

template <class SlotOf>
NumpyRows::Held NumpyRows::held_where(const Cache* kept, std::size_t num_slots, SlotOf slot_of,
                                      ParameterPointers params, std::span<const int> groups) const {
  if (kept == nullptr || (!groups.empty() && kept->group_position.empty())) return Held::kNo;
  for (std::size_t j = 0; j < num_slots; ++j) {
    const HeldSlot slot = slot_of(j);
    // The same bits (as memcmp; a few numbers, inline: this runs once per block per pass).
    const double* value = kept->values.data() + slot.start;
    for (int e = 0; e < slot.ambient; ++e) {
      std::uint64_t a = 0;
      std::uint64_t b = 0;
      std::memcpy(&a, params[j] + e, sizeof(a));
      std::memcpy(&b, value + e, sizeof(b));
      if (a != b) return Held::kNo;
    }
  }
  for (int g : groups) {
    if (kept->group_position[static_cast<std::size_t>(g)] < 0) return Held::kNo;
  }
  return kept->jacobians ? Held::kWithJacobians : Held::kResidualsOnly;
}

NumpyRows::Held NumpyRows::held_at(const Cache& kept, std::span<const HeldSlot> slots,
                                   ParameterPointers params, std::span<const int> groups) const {
  return held_where(
      &kept, slots.size(), [&](std::size_t j) { return slots[j]; }, params, groups);
}

NumpyRows::Held NumpyRows::held(std::span<const int> block_variables, ParameterPointers params,
                                std::span<const int> groups) const {
  return held_where(
      cache(), block_variables.size(), [&](std::size_t j) { return held_slot(block_variables[j]); },
      params, groups);
}

bool NumpyRows::ask_jacobians(Held state, bool jacobians) const {
  if (state == Held::kResidualsOnly && jacobians) {
    ahead_ = true;  // a linearization at the last cost pass's point
  } else if (state == Held::kNo && !jacobians && cache() != nullptr && cache()->ahead &&
             !cache()->linearized.load(std::memory_order_relaxed)) {
    ahead_ = false;  // a cost pass after one with Jacobians asked ahead: a rejected step
  }
  if (jacobians) return true;
  // No linearization is likely to follow: a function that computes its Jacobians only when
  // asked is not asked (one without the `jacobians` keyword computes them all the same).
  if (pass_jacobians_flag_ && likely_final_.load()) return false;
  return jacobians_returned_.load() && (!pass_jacobians_flag_ || ahead_);
}

void NumpyRows::refresh_cache(std::span<const int> groups, const double* base, bool jacobians,
                              bool asked) const {
  std::vector<int> wanted;
  std::size_t next = 0;
  for (int g = 0; g < groups_; ++g) {
    const bool is_asked = next < groups.size() && groups[next] == g;
    if (is_asked) ++next;
    if (is_asked || users_[static_cast<std::size_t>(g)].load(std::memory_order_relaxed) > 0)
      wanted.push_back(g);
  }
  // Its arrays freed first (unless a thread is reading it this instant): the function's new ones
  // can take their memory.
  publish(nullptr);
  auto fresh = std::make_unique<Cache>();
  fresh->evaluation = evaluate_groups(wanted, Source{{}, base}, asked, asked && !jacobians);
  fresh->jacobians = fresh->evaluation->has_jacobians();
  fresh->ahead = fresh->jacobians && !jacobians;
  fresh->linearized.store(jacobians, std::memory_order_relaxed);
  fresh->values.resize(values_size_);
  for (std::size_t v = 0; v < variables_.size(); ++v) {
    std::copy_n(base + variables_[v].offset, variables_[v].ambient,
                fresh->values.data() + variable_start_[v]);
  }
  fresh->group_position.assign(static_cast<std::size_t>(groups_), -1);
  for (std::size_t w = 0; w < wanted.size(); ++w) {
    fresh->group_position[static_cast<std::size_t>(wanted[w])] = static_cast<std::int64_t>(w);
  }
  publish(std::move(fresh));
}

std::shared_ptr<const RowsEvaluation> NumpyRows::evaluate_all(std::span<const int> block_variables,
                                                              ParameterPointers params,
                                                              bool jacobians) const {
  std::lock_guard<std::mutex> lock(cache_mutex_);
  const Held state = held(block_variables, params, {});
  if (serves(state, jacobians)) return cache()->evaluation;
  const bool asked = ask_jacobians(state, jacobians);
  // Its arrays freed first (unless a thread is reading it this instant): the function's new ones
  // can take their memory.
  publish(nullptr);
  auto fresh = std::make_unique<Cache>();
  fresh->evaluation =
      evaluate_groups(all_groups_, Source{params, nullptr}, asked, asked && !jacobians);
  fresh->jacobians = fresh->evaluation->has_jacobians();
  fresh->ahead = fresh->jacobians && !jacobians;
  fresh->linearized.store(jacobians, std::memory_order_relaxed);
  fresh->values.resize(values_size_);
  for (std::size_t j = 0; j < block_variables.size(); ++j) {
    const auto v = static_cast<std::size_t>(block_variables[j]);
    std::copy_n(params[j], variables_[v].ambient, fresh->values.data() + variable_start_[v]);
  }
  publish(std::move(fresh));
  return cache()->evaluation;
}

std::shared_ptr<const RowsEvaluation> NumpyRows::lookup(std::span<const int> block_variables,
                                                        ParameterPointers params,
                                                        std::span<const int> groups, bool jacobians,
                                                        std::vector<std::size_t>* positions) const {
  positions->resize(groups.size());
  {
    std::lock_guard<std::mutex> lock(cache_mutex_);
    const Held state = held(block_variables, params, groups);
    const bool hit = serves(state, jacobians);
    const double* base = hit ? nullptr : common_base(block_variables, params);
    if (base != nullptr) refresh_cache(groups, base, jacobians, ask_jacobians(state, jacobians));
    if (hit || base != nullptr) {
      for (std::size_t q = 0; q < groups.size(); ++q) {
        (*positions)[q] =
            static_cast<std::size_t>(cache()->group_position[static_cast<std::size_t>(groups[q])]) *
            static_cast<std::size_t>(group_rows_);
      }
      return cache()->evaluation;
    }
  }
  // Values that need not lie in an array of the problem's layout: these groups alone.
  for (std::size_t q = 0; q < groups.size(); ++q) {
    (*positions)[q] = q * static_cast<std::size_t>(group_rows_);
  }
  return evaluate_groups(groups, Source{params, nullptr}, jacobians);
}

const RowsEvaluation* NumpyRows::kept_group(std::span<const HeldSlot> slots,
                                            std::span<const int> block_variables,
                                            ParameterPointers params, int group, bool jacobians,
                                            std::size_t* w) const {
  const std::span<const int> groups(&group, 1);
  const Held state = cache() ? held_at(*cache(), slots, params, groups) : Held::kNo;
  const bool hit = serves(state, jacobians);
  const double* base = hit ? nullptr : common_base(block_variables, params);
  if (base != nullptr) refresh_cache(groups, base, jacobians, ask_jacobians(state, jacobians));
  if (!hit && base == nullptr) return nullptr;
  *w = static_cast<std::size_t>(cache()->group_position[static_cast<std::size_t>(group)]);
  return cache()->evaluation.get();
}

void NumpyRows::forget() const {
  std::lock_guard<std::mutex> lock(cache_mutex_);
  likely_final_.store(false);
  publish(nullptr);
}

void NumpyRows::acquire(std::span<const int> groups) const {
  if (single_block_) return;
  for (int g : groups) users_[static_cast<std::size_t>(g)].fetch_add(1, std::memory_order_relaxed);
}

void NumpyRows::release(std::span<const int> groups) const noexcept {
  if (single_block_) return;
  for (int g : groups) users_[static_cast<std::size_t>(g)].fetch_sub(1, std::memory_order_relaxed);
}

}  // namespace carat::python
