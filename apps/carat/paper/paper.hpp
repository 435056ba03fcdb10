#pragma once

// The sections of `carat paper`: each appends its Markdown and JSON to the report under
// construction. Shared here: the command's settings, the report, and the real KITTI 00 pair.

#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "carat/registration/frame.hpp"
#include "carat/residuals/gicp_block.hpp"
#include "iteration_trace.hpp"
#include "published.hpp"

namespace carat::cli::paper {

namespace fs = std::filesystem;

/// The settings of `carat paper`.
struct PaperArgs {
  std::string out = "carat-paper";      ///< output folder
  std::string data = "../shared/data";  ///< folder of the real data
  bool quick = false;                   ///< fewer trials and a smaller sequence
  bool json = false;                    ///< print the JSON instead of the report
  int threads = 0;                      ///< threads (0: all cores)
  std::uint64_t seed = 1;               ///< random seed
  double gre_excess_cauchy = 0.0;       ///< Cauchy scale on each GRE factor's excess (0: none)
  bool full_size = false;               ///< also Tables IV/V at the paper's problem size
  int full_size_frames = 4540;          ///< frames of that drive (the paper's KITTI 00 poses)
  double full_size_memory_gb = 0.0;  ///< factors' memory limit there, GB (0: 80 % of what is free)
};

/// A number as printf's `format` writes it.
std::string fmt(const char* format, double value);

/// The report under construction: Markdown text and the JSON twin.
struct Report {
  std::string markdown;
  nlohmann::json json;
  std::vector<fs::path> files;
};

/// The real KITTI 00 pair, aligned, with its full GICP factor at the alignment.
struct RealPair {
  std::shared_ptr<const Frame> target, source;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();  // T_target_source
  std::vector<GicpCorrespondence> correspondences;      // at T, within 1 m
  std::shared_ptr<const GicpBlock> block;               // over the correspondences
  std::array<double, 7> identity{}, pose{};
};

/// A published ATE as "mean ± std" (4 decimals).
std::string mean_std(const published::Ate& ate);

/// A count with thousands separators: 585417 -> "585,417".
std::string thousands(long long count);

/// The paper's Table IV/V row of exact sampling with M = `residuals`, or of all residuals
/// (`residuals` 0); none for another M.
std::optional<published::SamplingRow> published_sampling_row(int residuals);

/// Puts the paper's Table IV ATE and hours of `row` into a JSON row: paper_ate_mean,
/// paper_ate_std (metres), paper_hours.
void add_paper_table4(const published::SamplingRow& row, nlohmann::json* fields);

/// Puts the paper's Table V memory of `row` beside carat's `per_factor` bytes into a JSON row
/// (paper_correspondences_gb, paper_sampled_residuals_gb, paper_bytes_per_factor: what it held
/// during the optimization over its factors, GB read as 10^9 bytes; per_factor_ratio_to_paper)
/// and the same four as Markdown cells.
void add_paper_table5(const published::SamplingRow& row, double per_factor, nlohmann::json* fields,
                      std::vector<std::string>* cells);

/// Whether a data file is there; an entry that is there but is not a regular file (a FIFO, a
/// folder, a loop of links) is an error naming it, never a wait or a silent skip.
bool data_present(const fs::path& path);

/// The KITTI 00 pair from --data, or null when its files are absent.
std::unique_ptr<RealPair> load_kitti00(const PaperArgs& args);

/// Reduced H and b of a block at the relative pose T_target_source.
std::pair<Eigen::MatrixXd, Eigen::VectorXd> reduced_model(const ResidualBlock& block,
                                                          const Eigen::Isometry3d& T);

/// Table I: coreset time vs M at N = 30 000 (random J, e), beside Eigen's H, b, c once.
void table_one(const PaperArgs& args, Report* report);

/// Table II: NKLD between H of the full factor and H~ of random / exact sampling.
void table_two(const PaperArgs& args, const RealPair* pair, Report* report);

/// Fig. 4: error of the displacement H^-1 b of subsets vs the original points, under rotation
/// noise re-applied to the aligned pair; the SVG goes into `dir`.
void figure_four(const PaperArgs& args, const RealPair* pair, const fs::path& dir, Report* report);

/// Fig. 3: the rows exact sampling keeps (M = 29 and 512) over the source scan, coloured by
/// their axis, beside the full scan; the SVG goes into `dir`.
void figure_three(const PaperArgs& args, const RealPair* pair, const fs::path& dir, Report* report);

/// Tables III-V, Fig. 6 and Fig. 7 on a synthetic dense sequence; the SVGs go into `dir`.
void synthetic_tables(const PaperArgs& args, int threads, const fs::path& dir, Report* report);

/// Fig. 6: registration error and ATE per LM iteration of each trace; the SVGs go into `dir`.
void figure_six(const std::vector<IterationTrace>& traces, const fs::path& dir, Report* report);

/// Tables IV/V at the paper's problem size (`--full-size`): a drive of args.full_size_frames
/// frames scanned on demand, its dense graph, and GRE exact M = 29 / 256 / 1024 and lossless,
/// each solved when its factors fit in memory; full's memory from its factors' bytes.
void full_size_tables(const PaperArgs& args, int threads, Report* report);

/// The real KITTI 07 dense graph from a perturbed start.
void kitti07(const PaperArgs& args, int threads, Report* report);

}  // namespace carat::cli::paper
