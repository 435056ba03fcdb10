#include "covariance_output.hpp"

#include <charconv>

namespace carat::cli {

void add_covariance_options(CLI::App* command, CovarianceRequest* request, const std::string& what,
                            const std::string& gauge) {
  request->gauge = gauge;
  command
      ->add_option("--covariance", request->path,
                   "write the covariance of " + what +
                       " here: one line each, its id, then the d x d matrix row-major in carat's "
                       "tangent coordinates (docs/cli.md)")
      ->check(path_value());
  if (gauge.empty()) return;
  command
      ->add_option("--covariance-gauge", request->gauge,
                   "a singular H (a gauge freedom): error, or the pseudo-inverse (no variance "
                   "along the free directions)")
      ->check(CLI::IsMember({"error", "pseudo-inverse"}))
      ->capture_default_str();
}

void check_covariance_request(const CLI::App& command, const CovarianceRequest& request,
                              const std::vector<NamedInput>& inputs, const std::string& out_option,
                              const std::string& out_path) {
  if (command.get_option_no_throw("--covariance-gauge") != nullptr) {
    refuse_unused(command, "--covariance-gauge", !request.path.empty(), "without --covariance");
  }
  if (request.path.empty()) return;
  check_output_file("--covariance", request.path, inputs);
  if (!out_path.empty() && resolve_output_path(request.path) == resolve_output_path(out_path)) {
    throw UsageError("--covariance " + request.path + " is the same file as " + out_option + " " +
                     out_path + "; write them to different files");
  }
}

Covariance::Options covariance_options(const CovarianceRequest& request, int threads) {
  Covariance::Options options;
  if (!request.gauge.empty()) options.gauge = parse_covariance_gauge(request.gauge);
  options.num_threads = threads;
  return options;
}

void write_covariance_line(std::ostream& out, std::int64_t id, const Eigen::MatrixXd& covariance) {
  std::string line = std::to_string(id);
  char buffer[32];
  for (Eigen::Index r = 0; r < covariance.rows(); ++r) {
    for (Eigen::Index c = 0; c < covariance.cols(); ++c) {
      const auto result = std::to_chars(buffer, buffer + sizeof(buffer), covariance(r, c));
      line += ' ';
      line.append(buffer, result.ptr);
    }
  }
  line += '\n';
  out << line;
}

}  // namespace carat::cli
