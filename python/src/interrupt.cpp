#include "interrupt.hpp"

namespace carat::python {

InterruptCheck::InterruptCheck()
    : caller_(std::this_thread::get_id()), last_(std::chrono::steady_clock::now()) {}

std::function<void(std::size_t, std::size_t)> InterruptCheck::progress() {
  return [this](std::size_t, std::size_t) { check(); };
}

void InterruptCheck::check() {
  if (interrupted_.load(std::memory_order_relaxed)) throw Interrupted{};
  if (std::this_thread::get_id() != caller_) return;
  const auto now = std::chrono::steady_clock::now();
  if (now - last_ < std::chrono::milliseconds(50)) return;
  last_ = now;
  py::gil_scoped_acquire acquire;
  if (PyErr_CheckSignals() != 0) {
    PyObject *type = nullptr, *value = nullptr, *trace = nullptr;
    PyErr_Fetch(&type, &value, &trace);
    type_ = py::reinterpret_steal<py::object>(type);
    value_ = py::reinterpret_steal<py::object>(value);
    trace_ = py::reinterpret_steal<py::object>(trace);
    interrupted_.store(true, std::memory_order_relaxed);
    throw Interrupted{};
  }
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
