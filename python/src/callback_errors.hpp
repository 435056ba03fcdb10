#pragma once

/// The first exception a user's Python residual function raised during one call into carat (a
/// solve, a compression, an evaluation), kept with its traceback so that the call can re-raise it
/// once carat has returned: carat itself only sees a C++ error and a failed block.

#include <pybind11/pybind11.h>

#include <atomic>
#include <mutex>
#include <string>

namespace carat::python {

namespace py = pybind11;

/// The first Python exception of a problem's residual functions since clear().
class CallbackErrors {
 public:
  CallbackErrors() = default;
  CallbackErrors(const CallbackErrors&) = delete;
  CallbackErrors& operator=(const CallbackErrors&) = delete;
  ~CallbackErrors();

  /// With the GIL held: keeps `error` unless an earlier one is kept already.
  void record(const py::error_already_set& error);

  /// With the GIL held: keeps a new exception of Python type `type` (e.g. PyExc_ValueError) with
  /// `message`, unless an earlier one is kept already.
  void record(PyObject* type, const std::string& message);

  /// Whether an exception is kept (any thread, no GIL needed).
  bool failed() const { return failed_.load(std::memory_order_acquire); }

  /// With the GIL held: forgets the kept exception.
  void clear();

  /// With the GIL held: when an exception is kept, raises it in Python (its traceback included)
  /// and forgets it; returns otherwise.
  void raise_if_failed();

 private:
  void keep(py::object type, py::object value, py::object trace);

  mutable std::mutex mutex_;
  std::atomic<bool> failed_{false};
  py::object type_, value_, trace_;
};

}  // namespace carat::python
