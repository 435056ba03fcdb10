// carat: the command-line tool. Each subcommand lives in its own cmd_*.cpp.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <new>
#include <string>

#include "carat/base/blas_kernels.hpp"
#include "carat/base/version.hpp"
#include "cli_support.hpp"
#include "commands.hpp"
#include "mpi_launch.hpp"

namespace {

/// A message as one line of printable text: control bytes (line breaks, escapes) become '?'.
std::string one_line(const std::string& message) {
  std::string out(message);
  for (char& c : out) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = '?';
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  // First of all: OpenBLAS's kernels for this CPU where it fell back to its oldest ones (a
  // restart with OPENBLAS_CORETYPE set; docs/cli.md, "BLAS kernels").
  carat::use_cpu_blas_kernels(argv);
  // Under mpirun only rank 0 prints (help, usage errors, errors: one message, not one per rank),
  // and only `carat map` runs on the other ranks; every other subcommand runs on rank 0 alone.
  const bool quiet = carat::cli::mpi_launch().secondary();
  // Before any thread starts: interruptions remove carat's temporary files and folders. The other
  // ranks end half a second after a signal, once rank 0 has removed its temporaries: mpirun
  // kills every rank with SIGKILL as soon as one ends by a signal.
  carat::cli::install_interrupt_cleanup(quiet ? 500 : 0);
  CLI::App app{"carat: sparse nonlinear least squares with exact residual-block compression"};
  app.require_subcommand(1);
  const carat::BlasKernels blas = carat::blas_kernels();
  // The version, then the BLAS kernels the solves run on (OpenBLAS reports them).
  app.set_version_flag(
      "--version",
      std::string("carat ") + carat::version() +
          (blas.library.empty() ? "" : "\nBLAS: " + blas.library + ", kernels " + blas.core));
  carat::cli::CommandRegistry registry;
  carat::cli::register_demo(app, registry);
  carat::cli::register_solve_g2o(app, registry);
  carat::cli::register_coreset_check(app, registry);
  carat::cli::register_align(app, registry);
  carat::cli::register_ate(app, registry);
  carat::cli::register_map(app, registry);
  carat::cli::register_odometry(app, registry);
  carat::cli::register_simulate(app, registry);
  carat::cli::register_simulate_bal(app, registry);
  carat::cli::register_solve_bal(app, registry);
  carat::cli::register_paper(app, registry);
  if (argc > 1 && argv[1][0] != '-') {
    bool known = false;
    std::string names;
    const CLI::App& root = app;
    for (const CLI::App* sub : root.get_subcommands([](const CLI::App*) { return true; })) {
      known = known || sub->get_name() == argv[1];
      names += (names.empty() ? "" : ", ") + sub->get_name();
    }
    if (!known) {
      // Every rank parses the same arguments and fails alike: the other ranks end quietly with
      // status 0 and leave the message and the status to rank 0 (a rank ending non-zero first
      // would have mpirun kill rank 0 before it prints).
      if (quiet) return 0;
      std::fprintf(stderr, "carat: usage error: unknown subcommand %s (valid: %s)\n",
                   carat::quote_bytes(argv[1]).c_str(), names.c_str());
      return 2;
    }
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return quiet ? 0 : carat::cli::finish_standard_output(app.exit(e));
  } catch (const CLI::CallForAllHelp& e) {
    return quiet ? 0 : carat::cli::finish_standard_output(app.exit(e));
  } catch (const CLI::CallForVersion& e) {
    return quiet ? 0 : carat::cli::finish_standard_output(app.exit(e));
  } catch (const CLI::ParseError& e) {
    if (!quiet) {
      std::fprintf(stderr, "carat: usage error: %s (see --help)\n", one_line(e.what()).c_str());
    }
    return quiet ? 0 : 2;  // rank 0 reports it (as for an unknown subcommand above)
  }
  if (quiet) {
    const CLI::App& root = app;
    for (const CLI::App* sub : root.get_subcommands()) {
      if (sub->get_name() != "map") return 0;  // rank 0 runs it, alone
    }
  }
  int status = 0;
  // One line on stderr; every rank of an mpirun job but 0 stays silent (rank 0 reports theirs).
  const auto report = [quiet](const std::string& line) {
    if (!quiet) std::fprintf(stderr, "carat: %s\n", one_line(line).c_str());
  };
  try {
    status = registry.run_selected();
  } catch (const carat::cli::UsageError& e) {
    report(std::string("usage error: ") + e.what());
    status = quiet ? 0 : 2;  // the same on every rank: rank 0 reports it, with the status
  } catch (const std::bad_alloc&) {
    report("error: out of memory (the inputs or options need more memory than this machine has)");
    status = 1;
  } catch (const std::filesystem::filesystem_error& e) {
    // "PATH: reason", not the library's "filesystem error: operation: reason [PATH]".
    const std::string path = e.path1().empty() ? std::string("a path") : e.path1().string();
    report("error: " + path + ": " + e.code().message());
    status = 1;
  } catch (const std::exception& e) {
    report(std::string("error: ") + e.what());
    status = 1;
  } catch (...) {
    report("error: an unknown error ended the run");
    status = 1;
  }
  return quiet ? status : carat::cli::finish_standard_output(status);
}
