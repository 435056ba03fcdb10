#include "callback_errors.hpp"

#include <utility>

namespace carat::python {

CallbackErrors::~CallbackErrors() {
  if (!type_ && !value_ && !trace_) return;
  if (!Py_IsInitialized()) {  // the interpreter is gone: nothing may be released any more
    (void)type_.release();
    (void)value_.release();
    (void)trace_.release();
    return;
  }
  py::gil_scoped_acquire gil;
  type_ = py::object();
  value_ = py::object();
  trace_ = py::object();
}

void CallbackErrors::keep(py::object type, py::object value, py::object trace) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (failed_.load(std::memory_order_relaxed)) return;
  type_ = std::move(type);
  value_ = std::move(value);
  trace_ = std::move(trace);
  failed_.store(true, std::memory_order_release);
}

void CallbackErrors::record(const py::error_already_set& error) {
  keep(error.type(), error.value(), error.trace());
}

void CallbackErrors::record(PyObject* type, const std::string& message) {
  py::object exception_type = py::reinterpret_borrow<py::object>(type);
  keep(exception_type, exception_type(message), py::none());
}

void CallbackErrors::clear() {
  std::lock_guard<std::mutex> lock(mutex_);
  type_ = py::object();
  value_ = py::object();
  trace_ = py::object();
  failed_.store(false, std::memory_order_release);
}

void CallbackErrors::raise_if_failed() {
  py::object type, value, trace;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!failed_.load(std::memory_order_relaxed)) return;
    type = std::move(type_);
    value = std::move(value_);
    trace = std::move(trace_);
    failed_.store(false, std::memory_order_release);
  }
  PyErr_Restore(type.release().ptr(), value.release().ptr(),
                trace.is_none() ? nullptr : trace.release().ptr());
  throw py::error_already_set();
}

}  // namespace carat::python
