#include "interrupt.hpp"

namespace carat::python {

InterruptCheck::InterruptCheck()
    : caller_(std::this_thread::get_id()), last_(std::chrono::steady_clock::now()) {}

std::function<void(std::size_t, std::size_t)> InterruptCheck::progress() {
  return [this](std::size_t, std::size_t) { check(); };
}

IterationCallback InterruptCheck::iteration_callback() {
  return [this](const IterationSummary&) {
    return poll() ? CallbackResult::kAbort : CallbackResult::kContinue;
  };
}

void InterruptCheck::check() {
  if (poll()) throw Interrupted{};
}

bool InterruptCheck::poll() {
  if (interrupted_.load(std::memory_order_relaxed)) return true;
  if (std::this_thread::get_id() != caller_) return false;
  const auto now = std::chrono::steady_clock::now();
  if (now - last_ < std::chrono::milliseconds(50)) return false;
  last_ = now;
  py::gil_scoped_acquire acquire;
  if (PyErr_CheckSignals() != 0) {
    PyObject *type = nullptr, *value = nullptr, *trace = nullptr;
    PyErr_Fetch(&type, &value, &trace);
    type_ = py::reinterpret_steal<py::object>(type);
    value_ = py::reinterpret_steal<py::object>(value);
    trace_ = py::reinterpret_steal<py::object>(trace);
    interrupted_.store(true, std::memory_order_relaxed);
    return true;
  }
  return false;
}

void InterruptCheck::raise() {
  if (type_) {
    PyErr_Restore(type_.release().ptr(), value_.release().ptr(), trace_.release().ptr());
  } else {
    PyErr_SetNone(PyExc_KeyboardInterrupt);
  }
  throw py::error_already_set();
}

}  // namespace carat::python
