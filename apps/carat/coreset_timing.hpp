#pragma once

// How `carat coreset-check` and Table I of `carat paper` measure the coreset: random rows drawn
// one trial at a time, and per trial select_coreset_rows() for each requested target beside
// forming H, b, c once with Eigen (J^T J, J^T e, e^T e) on the same rows, each call timed with
// its own Stopwatch. The Eigen reference runs before the coresets on odd trials and after them
// on even ones, so that neither always finds the rows in cache after the other.

#include <Eigen/Core>
#include <cstdint>
#include <random>
#include <span>
#include <vector>

#include "carat/coreset/row_coreset.hpp"

namespace carat::cli {

/// Rows as select_coreset_rows() takes them: N x D, row-major.
using RowMajorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// Random rows, trial after trial, from one seeded generator.
class RandomRowSource {
 public:
  /// Entries are `scale` times standard normal draws (unitless) from a generator seeded `seed`.
  RandomRowSource(std::uint64_t seed, double scale);

  /// The next trial's rows: J (rows x dim) filled first, row by row, then e (rows).
  void draw(long rows, int dim, RowMajorMatrix* J, Eigen::VectorXd* e);

 private:
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_;
  double scale_;
};

/// The coresets of one trial and the wall times of its calls.
struct CoresetTrial {
  std::vector<RowCoreset> coresets;  ///< one per options entry, in the same order
  std::vector<double> coreset_ms;    ///< milliseconds of each select_coreset_rows() call
  double reference_ms = 0.0;         ///< milliseconds of forming H, b, c once with Eigen
};

/// Runs select_coreset_rows(J, e, options[k]) for every k and the Eigen reference on the same
/// rows (from a column-major copy of J made before any timing); `trial` (0, 1, ...) sets the
/// order as the header says. Throws carat::Error as select_coreset_rows() does.
CoresetTrial time_coreset_trial(const RowMajorMatrix& J, const Eigen::VectorXd& e,
                                std::span<const RowCoresetOptions> options, int trial);

}  // namespace carat::cli
