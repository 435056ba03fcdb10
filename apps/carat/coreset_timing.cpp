#include "coreset_timing.hpp"

#include <utility>

#include "carat/base/stopwatch.hpp"

namespace carat::cli {
namespace {

/// Where the reference's results go, so that the compiler cannot leave the products out.
volatile double reference_sink = 0.0;

}  // namespace

RandomRowSource::RandomRowSource(std::uint64_t seed, double scale) : rng_(seed), scale_(scale) {}

void RandomRowSource::draw(long rows, int dim, RowMajorMatrix* J, Eigen::VectorXd* e) {
  J->resize(rows, dim);
  e->resize(rows);
  for (long i = 0; i < J->size(); ++i) J->data()[i] = scale_ * normal_(rng_);
  for (long i = 0; i < e->size(); ++i) (*e)[i] = scale_ * normal_(rng_);
}

CoresetTrial time_coreset_trial(const RowMajorMatrix& J, const Eigen::VectorXd& e,
                                std::span<const RowCoresetOptions> options, int trial) {
  const Eigen::MatrixXd J_columns = J;  // column-major, as Eigen multiplies fastest
  CoresetTrial out;
  const auto run_reference = [&] {
    const Stopwatch stopwatch;
    const Eigen::MatrixXd H = J_columns.transpose() * J_columns;
    const Eigen::VectorXd b = J_columns.transpose() * e;
    const double c = e.squaredNorm();
    out.reference_ms = stopwatch.elapsed_ms();
    reference_sink = reference_sink + H(0, 0) + b[0] + c;
  };
  if (trial % 2 == 1) run_reference();
  for (const RowCoresetOptions& o : options) {
    const Stopwatch stopwatch;
    RowCoreset coreset = select_coreset_rows(J, e, o);
    out.coreset_ms.push_back(stopwatch.elapsed_ms());
    out.coresets.push_back(std::move(coreset));
  }
  if (trial % 2 == 0) run_reference();
  return out;
}

}  // namespace carat::cli
