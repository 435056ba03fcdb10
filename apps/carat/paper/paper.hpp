#pragma once

// The sections of `carat paper`: each appends its Markdown and JSON to the report under
// construction. Shared here: the command's settings, the report, and the real KITTI 00 pair.

#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "carat/registration/frame.hpp"
#include "carat/residuals/gicp_block.hpp"
#include "iteration_trace.hpp"

namespace carat::cli::paper {

namespace fs = std::filesystem;

/// The settings of `carat paper`.
struct PaperArgs {
  std::string out = "carat-paper";
  std::string data = "../shared/data";
  bool quick = false;
  bool json = false;
  int threads = 0;
  std::uint64_t seed = 1;
  double gre_excess_cauchy = 0.0;
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

/// The real KITTI 07 dense graph from a perturbed start.
void kitti07(const PaperArgs& args, int threads, Report* report);

}  // namespace carat::cli::paper
