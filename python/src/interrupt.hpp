#pragma once

/// Long calls of the Python module: the GIL released while carat works, and Ctrl-C honoured at
/// the progress points carat's stages report, so that an interrupted call ends early with
/// KeyboardInterrupt and leaves the interpreter usable.

#include <pybind11/pybind11.h>

#include <atomic>
#include <chrono>
#include <cstddef>
#include <functional>
#include <optional>
#include <thread>
#include <type_traits>
#include <utility>

#include "carat/base/interruption.hpp"
#include "carat/solver/solver_options.hpp"

namespace carat::python {

namespace py = pybind11;

/// Thrown through carat's stages from a progress callback after Ctrl-C (never seen by Python).
struct Interrupted {};

/// Pending signals of one long call: progress() checks them (at most every 50 ms, and only on
/// the thread that made the call, the one Python runs its signal handlers on).
class InterruptCheck {
 public:
  InterruptCheck();

  /// A progress callback for carat's stages: throws Interrupted once a signal handler raised.
  std::function<void(std::size_t, std::size_t)> progress();

  /// An iteration callback for carat's solver: kAbort once a signal handler raised.
  IterationCallback iteration_callback();

  /// Checks (at most every 50 ms, on the calling thread, taking the GIL): true once a signal
  /// handler has raised.
  bool poll();

  /// poll(), throwing Interrupted when it is true.
  void check();

  /// Whether a signal handler has raised during the call.
  bool interrupted() const { return interrupted_.load(std::memory_order_relaxed); }

  /// With the GIL held: restores the exception a signal handler raised and throws it to Python.
  [[noreturn]] void raise();

 private:
  std::thread::id caller_;
  std::atomic<bool> interrupted_{false};
  std::chrono::steady_clock::time_point last_;
  py::object type_, value_, trace_;
};

/// Runs f(check) with the GIL released, where check is an InterruptCheck whose progress() f
/// (or iteration_callback()) hands to carat, and which carat's interruption points on this
/// thread (carat/base/interruption.hpp: the coreset's levels and eliminations) also poll; an
/// interruption comes back as the Python exception its handler raised (KeyboardInterrupt for
/// Ctrl-C), whether f ended by Interrupted or returned after a solve aborted. Any other exception
/// propagates as it is.
template <typename F>
auto run_released(F&& f) {
  InterruptCheck check;
  const InterruptionScope scope([&check] { check.check(); });
  using Result = std::invoke_result_t<F, InterruptCheck&>;
  if constexpr (std::is_void_v<Result>) {
    bool interrupted = false;
    {
      py::gil_scoped_release release;
      try {
        f(check);
      } catch (const Interrupted&) {
        interrupted = true;
      }
    }
    if (interrupted || check.interrupted()) check.raise();
  } else {
    std::optional<Result> result;
    {
      py::gil_scoped_release release;
      try {
        result.emplace(f(check));
      } catch (const Interrupted&) {
      }
    }
    if (!result || check.interrupted()) check.raise();
    return std::move(*result);
  }
}

}  // namespace carat::python
