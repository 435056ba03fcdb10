#pragma once

// Subcommand registration for the carat CLI.

#include <CLI/CLI.hpp>
#include <functional>
#include <vector>

namespace carat::cli {

/// Subcommands and the action to run for the one that was parsed.
class CommandRegistry {
 public:
  /// Remembers `action` to run when `command` was selected on the command line.
  void add(CLI::App* command, std::function<int()> action) {
    entries_.push_back({command, std::move(action)});
  }
  /// Runs the selected subcommand's action; returns its exit code.
  int run_selected() const {
    for (const auto& [command, action] : entries_) {
      if (command->parsed()) return action();
    }
    return 2;
  }

 private:
  std::vector<std::pair<CLI::App*, std::function<int()>>> entries_;
};

/// `carat demo`: the main job on the built-in synthetic world.
void register_demo(CLI::App& app, CommandRegistry& registry);
/// `carat solve-g2o`: optimize a g2o pose graph.
void register_solve_g2o(CLI::App& app, CommandRegistry& registry);
/// `carat align`: GICP scan matching of two scans.
void register_align(CLI::App& app, CommandRegistry& registry);
/// `carat coreset-check`: exactness and speed of the coreset on random rows.
void register_coreset_check(CLI::App& app, CommandRegistry& registry);
/// `carat ate`: absolute trajectory error of an estimate against a reference.
void register_ate(CLI::App& app, CommandRegistry& registry);
/// `carat map`: dense global registration on real scans.
void register_map(CLI::App& app, CommandRegistry& registry);
/// `carat odometry`: GICP odometry from a folder of scans.
void register_odometry(CLI::App& app, CommandRegistry& registry);
/// `carat simulate`: write a simulated LiDAR drive to disk.
void register_simulate(CLI::App& app, CommandRegistry& registry);
/// `carat simulate-bal`: write a synthetic bundle-adjustment problem in the BAL format.
void register_simulate_bal(CLI::App& app, CommandRegistry& registry);
/// `carat solve-bal`: bundle adjustment of a BAL problem.
void register_solve_bal(CLI::App& app, CommandRegistry& registry);
/// `carat paper`: regenerate the paper's tables and figures.
void register_paper(CLI::App& app, CommandRegistry& registry);

}  // namespace carat::cli
