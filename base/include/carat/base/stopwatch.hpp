#pragma once

/// Wall-clock time of a stage, from the monotonic clock (std::chrono::steady_clock): readings
/// never go backwards, whatever happens to the system time.

#include <chrono>

namespace carat {

/// Measures the wall time since it was started or last restarted.
class Stopwatch {
 public:
  /// Starts now.
  Stopwatch() : start_(Clock::now()) {}

  /// Seconds since the start (or the last restart); >= 0, non-decreasing between restarts.
  double elapsed_s() const { return std::chrono::duration<double>(Clock::now() - start_).count(); }

  /// Milliseconds since the start (or the last restart); elapsed_s() in milliseconds.
  double elapsed_ms() const {
    return std::chrono::duration<double, std::milli>(Clock::now() - start_).count();
  }

  /// Starts again from now; returns the seconds that had elapsed before.
  double restart() {
    const Clock::time_point now = Clock::now();
    const double seconds = std::chrono::duration<double>(now - start_).count();
    start_ = now;
    return seconds;
  }

 private:
  using Clock = std::chrono::steady_clock;
  Clock::time_point start_;
};

}  // namespace carat
