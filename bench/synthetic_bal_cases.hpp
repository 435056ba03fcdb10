#pragma once
// The synthetic bundle-adjustment problems the comparison benches share (bal_compare beside
// Ceres, gtsam_compare beside GTSAM): simulate_bal() settings, seed 7, the default start.
#include <vector>

#include "carat/sim/bal_scene.hpp"

/// One generated problem: its name in the JSON and simulate_bal()'s options.
struct SyntheticBalCase {
  const char* name;                     ///< e.g. "ring-16x22106"
  carat::BalSimulationOptions options;  ///< layout, cameras, points, views; seed 7
};

/// The three problems (`quick`: the first alone).
inline std::vector<SyntheticBalCase> synthetic_bal_cases(bool quick) {
  const auto make = [](const char* name, carat::BalLayout layout, int cameras, int points,
                       int views) {
    SyntheticBalCase c{name, {}};
    c.options.layout = layout;
    c.options.cameras = cameras;
    c.options.points = points;
    c.options.observations_per_point = views;
    c.options.seed = 7;
    return c;
  };
  std::vector<SyntheticBalCase> cases = {
      make("ring-16x22106", carat::BalLayout::kRing, 16, 22106, 4),
      make("ring-100x20000", carat::BalLayout::kRing, 100, 20000, 8),
      make("street-500x60000", carat::BalLayout::kStreet, 500, 60000, 5)};
  if (quick) cases.resize(1);
  return cases;
}
