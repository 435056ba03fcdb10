#pragma once

/// Cooperative interruption of long computations. Loops that can run for seconds (the coreset's
/// levels and eliminations) call interruption_point() between their steps; a caller that wants
/// to end such a call early (the Python module on Ctrl-C) installs a check for its thread with an
/// InterruptionScope, and an exception the check throws leaves the computation there. Library
/// code installs no check, so without one interruption_point() costs one thread-local load.

#include <functional>

namespace carat {

/// Installs `check` for the calling thread while the scope lives (scopes nest; the innermost
/// check runs). Computations that run on this thread call it at their interruption points.
class InterruptionScope {
 public:
  /// `check` is called at each interruption point of this thread; it may throw to end the work.
  explicit InterruptionScope(std::function<void()> check);
  /// Restores the check that was installed before (or none).
  ~InterruptionScope();
  InterruptionScope(const InterruptionScope&) = delete;
  InterruptionScope& operator=(const InterruptionScope&) = delete;

 private:
  std::function<void()> check_;
  const std::function<void()>* previous_;
};

/// Calls the check installed on this thread, if any (which may throw); does nothing otherwise.
void interruption_point();

}  // namespace carat
