// What the sections of `carat paper` share: number formatting, data files, the KITTI 00 pair.
#include <cstdio>
#include <system_error>

#include "carat/base/error.hpp"
#include "carat/registration/align.hpp"
#include "carat/registration/correspondences.hpp"
#include "carat/registration/io/kitti_io.hpp"
#include "carat/solver/se3.hpp"
#include "cli_support.hpp"
#include "paper.hpp"

namespace carat::cli::paper {

std::string fmt(const char* format, double value) {
  char text[64];
  std::snprintf(text, sizeof(text), format, value);
  return text;
}

std::string mean_std(const published::Ate& ate) {
  return fmt("%.4f", ate.mean) + " ± " + fmt("%.4f", ate.std);
}

std::string thousands(long long count) {
  std::string digits = std::to_string(count), out;
  for (std::size_t k = 0; k < digits.size(); ++k) {
    if (k > 0 && (digits.size() - k) % 3 == 0) out += ',';
    out += digits[k];
  }
  return out;
}

std::optional<published::SamplingRow> published_sampling_row(int residuals) {
  for (const auto& row : published::kTables4And5)
    if (row.residuals == residuals) return row;
  return std::nullopt;
}

void add_paper_table4(const published::SamplingRow& row, nlohmann::json* fields) {
  (*fields)["paper_ate_mean"] = row.ate.mean;
  (*fields)["paper_ate_std"] = row.ate.std;
  (*fields)["paper_hours"] = row.hours;
}

void add_paper_table5(const published::SamplingRow& row, double per_factor, nlohmann::json* fields,
                      std::vector<std::string>* cells) {
  const double held_gb = row.residuals == 0 ? row.correspondences_gb : row.sampled_residuals_gb;
  const double paper_per_factor = held_gb * 1e9 / published::kSequence00Factors;
  (*fields)["paper_correspondences_gb"] = row.correspondences_gb;
  (*fields)["paper_sampled_residuals_gb"] = row.sampled_residuals_gb;
  (*fields)["paper_bytes_per_factor"] = paper_per_factor;
  (*fields)["per_factor_ratio_to_paper"] = per_factor / paper_per_factor;
  cells->insert(cells->end(),
                {fmt("%.2f", row.correspondences_gb), fmt("%.2f", row.sampled_residuals_gb),
                 format_bytes(paper_per_factor), fmt("%.2f", per_factor / paper_per_factor)});
}

bool data_present(const fs::path& path) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (ec && ec != std::errc::no_such_file_or_directory) {
    throw Error(path.string() + ": " + ec.message());
  }
  if (!fs::exists(status)) return false;
  if (!fs::is_regular_file(status)) {
    throw Error(path.string() + ": is not a regular file (the paper's data are regular files)");
  }
  return true;
}

std::unique_ptr<RealPair> load_kitti00(const PaperArgs& args) {
  const fs::path dir = fs::path(args.data) / "kitti00_pair";
  if (!data_present(dir / "000000.bin") || !data_present(dir / "000001.bin")) return nullptr;
  auto pair = std::make_unique<RealPair>();
  PreprocessOptions preprocess;
  preprocess.voxel_size = 0.25;
  preprocess.num_threads = 2;
  pair->target = preprocess_frame(read_kitti_bin(dir / "000000.bin", KittiFormat::kXyz), preprocess,
                                  (dir / "000000.bin").string());
  pair->source = preprocess_frame(read_kitti_bin(dir / "000001.bin", KittiFormat::kXyz), preprocess,
                                  (dir / "000001.bin").string());
  AlignSettings settings;
  settings.num_threads = 2;
  pair->T = align(pair->target->cloud(), pair->target->tree(), pair->source->cloud(),
                  Eigen::Isometry3d::Identity(), settings)
                .T_target_source;
  pair->correspondences = find_correspondences(pair->target->cloud(), pair->target->tree(),
                                               pair->source->cloud(), pair->T, 1.0);
  pair->block = std::make_shared<const GicpBlock>(pair->correspondences, pair->T);
  se3::to_storage(Eigen::Isometry3d::Identity(), pair->identity.data());
  se3::to_storage(pair->T, pair->pose.data());
  return pair;
}

/// Reduced H and b of a block at the relative pose T_target_source.
std::pair<Eigen::MatrixXd, Eigen::VectorXd> reduced_model(const ResidualBlock& block,
                                                          const Eigen::Isometry3d& T) {
  double identity[7], pose[7];
  se3::to_storage(Eigen::Isometry3d::Identity(), identity);
  se3::to_storage(T, pose);
  const double* values[2] = {identity, pose};
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(6, 6);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(6);
  block.accumulate(values, H, b);
  return {H, b};
}

}  // namespace carat::cli::paper
