#pragma once

/// Wall times of a pipeline's named stages, in the order they first ran: the one place a
/// pipeline reports where its time went, beside the algorithms instead of through them.

#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace carat {

/// Seconds per named stage, in first-run order; a stage run again adds to its time.
class StageTimes {
 public:
  /// Adds `seconds` (wall time, >= 0) to `stage`, appending the stage when it is new.
  void add(std::string_view stage, double seconds) {
    for (auto& [name, total] : entries_) {
      if (name == stage) {
        total += seconds;
        return;
      }
    }
    entries_.emplace_back(std::string(stage), seconds);
  }
  /// Seconds of `stage`; 0 when it did not run.
  double seconds(std::string_view stage) const {
    for (const auto& [name, total] : entries_)
      if (name == stage) return total;
    return 0.0;
  }
  /// Whether `stage` ran.
  bool ran(std::string_view stage) const {
    for (const auto& entry : entries_)
      if (entry.first == stage) return true;
    return false;
  }
  /// Sum over the stages, seconds.
  double total_s() const {
    double sum = 0.0;
    for (const auto& entry : entries_) sum += entry.second;
    return sum;
  }
  /// (stage, seconds) in first-run order.
  const std::vector<std::pair<std::string, double>>& entries() const { return entries_; }

 private:
  std::vector<std::pair<std::string, double>> entries_;
};

}  // namespace carat
