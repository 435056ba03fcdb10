// carat: the command-line tool. Each subcommand lives in its own cmd_*.cpp.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>

#include "commands.hpp"

int main(int argc, char** argv) {
  CLI::App app{"carat: sparse nonlinear least squares with exact residual-block compression"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "carat 0.1.0");
  carat::cli::CommandRegistry registry;
  carat::cli::register_demo(app, registry);
  carat::cli::register_solve_g2o(app, registry);
  carat::cli::register_coreset_check(app, registry);
  carat::cli::register_align(app, registry);
  carat::cli::register_ate(app, registry);
  carat::cli::register_map(app, registry);
  carat::cli::register_simulate(app, registry);
  carat::cli::register_paper(app, registry);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    return registry.run_selected();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "carat: error: %s\n", e.what());
    return 1;
  }
}
