#pragma once

// --covariance FILE and --covariance-gauge of solve-g2o, solve-bal and map: the options, their
// checks, and the file: one line per free variable, its id, then its d x d covariance row-major
// (shortest round-trip decimals), in carat's tangent coordinates (docs/cli.md).

#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include "carat/base/atomic_file.hpp"
#include "carat/solver/covariance.hpp"
#include "cli_support.hpp"

namespace carat::cli {

/// What --covariance and --covariance-gauge ask for.
struct CovarianceRequest {
  std::string path;   ///< --covariance; empty: none
  std::string gauge;  ///< --covariance-gauge: "error" or "pseudo-inverse" (empty: error)
};

/// Registers --covariance (`what`: the variables written, e.g. "every free vertex") and, unless
/// `gauge` is empty, --covariance-gauge (default `gauge`) on `command`.
void add_covariance_options(CLI::App* command, CovarianceRequest* request, const std::string& what,
                            const std::string& gauge);

/// Before any work: --covariance-gauge only with --covariance; the path as check_output_file()
/// checks it, and not the same file as `out_option`'s `out_path` (may be empty). Throws
/// UsageError.
void check_covariance_request(const CLI::App& command, const CovarianceRequest& request,
                              const std::vector<NamedInput>& inputs, const std::string& out_option,
                              const std::string& out_path);

/// The library's options for the request (the gauge), `threads` threads.
Covariance::Options covariance_options(const CovarianceRequest& request, int threads);

/// Appends "id c00 c01 ... c(d-1)(d-1)\n" to `out`.
void write_covariance_line(std::ostream& out, std::int64_t id, const Eigen::MatrixXd& covariance);

}  // namespace carat::cli
