// The quadratic row coreset: exactness (relative error) over sizes, dimensions, scales and
// degenerate data; output sizes; determinism; bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <sstream>
#include <string>
#include <tuple>

#include "carat/base/error.hpp"
#include "carat/coreset/caratheodory.hpp"
#include "carat/coreset/compress.hpp"
#include "carat/coreset/quadratic_model.hpp"
#include "carat/coreset/row_coreset.hpp"
#include "carat/solver/jacobian_checker.hpp"
#include "carat/solver/manifold.hpp"
#include "coreset_test_blocks.hpp"
#include "coreset_test_support.hpp"

namespace carat {
namespace {

using test::coreset_error;
using test::expect_error;
using test::random_rows;
using test::RowMatrix;
using test::Rows;

// (N, M (0 = minimum), K, D, scale, seed)
using Case = std::tuple<long, int, int, int, double, std::uint64_t>;
class CoresetPropertyTest : public ::testing::TestWithParam<Case> {};

/// A case's name: its rows, target, clusters, dimension and seed (the seed makes it unique).
std::string case_name(const ::testing::TestParamInfo<Case>& param_info) {
  const auto [n, target, clusters, dim, scale, seed] = param_info.param;
  std::ostringstream name;  // (a stream: GCC 12 misreads chained string + as overlapping copies)
  name << "N" << n << "_M" << target << "_K" << clusters << "_D" << dim << "_seed" << seed;
  return name.str();
}

TEST_P(CoresetPropertyTest, ExactAndOfTheRequestedSize) {
  const auto [n, target, clusters, dim, scale, seed] = GetParam();
  const Rows rows = random_rows(n, dim, scale, seed);
  RowCoresetOptions options;
  options.target_rows = target;
  options.clusters = clusters;
  options.seed = seed;
  const RowCoreset coreset = select_coreset_rows(rows.J, rows.e, options);
  const long m = target == 0 ? minimum_coreset_rows(dim) : target;
  EXPECT_EQ(static_cast<long>(coreset.rows.size()), std::min(n, m));
  EXPECT_TRUE(std::is_sorted(coreset.rows.begin(), coreset.rows.end()));
  for (double w : coreset.weights) EXPECT_GT(w, 0.0);
  const QuadraticModelError err = coreset_error(rows, coreset);
  EXPECT_LE(err.H, 1e-12);
  EXPECT_LE(err.b, 1e-12);
  EXPECT_LE(err.c, 1e-12);
  // No weight mass is lost: the weights sum to N.
  const double mass = std::accumulate(coreset.weights.begin(), coreset.weights.end(), 0.0);
  EXPECT_NEAR(mass, static_cast<double>(n), 1e-9 * static_cast<double>(n));
}

INSTANTIATE_TEST_SUITE_P(
    Sizes, CoresetPropertyTest,
    ::testing::Values(Case{29, 0, 64, 6, 1.0, 1}, Case{30, 0, 64, 6, 1.0, 2},
                      Case{100, 0, 64, 6, 1.0, 3}, Case{1000, 0, 64, 6, 1.0, 4},
                      Case{30000, 0, 64, 6, 1.0, 5}, Case{30000, 64, 64, 6, 1.0, 6},
                      Case{30000, 256, 64, 6, 1.0, 7}, Case{30000, 1024, 64, 6, 1.0, 8},
                      Case{20000, 0, 40, 6, 1.0, 9}, Case{30000, 0, 64, 6, 1e-6, 10},
                      Case{30000, 0, 64, 6, 1e6, 11}, Case{5000, 0, 128, 12, 1.0, 12},
                      Case{5000, 200, 128, 12, 1e3, 13}, Case{3000, 0, 16, 2, 1.0, 14},
                      Case{1000000, 0, 64, 6, 1.0, 15}, Case{30000, 0, 128, 12, 1e-6, 16},
                      Case{30000, 0, 93, 12, 1e6, 17}, Case{3000, 29, 30, 6, 1.0, 18},
                      Case{300000, 512, 64, 6, 1e-3, 19}, Case{10000, 0, 64, 3, 1e6, 20},
                      Case{91, 0, 128, 12, 1.0, 21}, Case{200, 0, 128, 12, 1.0, 22}),
    case_name);

// Every reduced dimension from 1 to 16 with the default clusters: rows up to 15 columns travel
// packed (and are lifted on the fly, 8 or 16 doubles a row), 16 columns lifted; both exact.
INSTANTIATE_TEST_SUITE_P(
    EveryDimension, CoresetPropertyTest,
    ::testing::Values(Case{4000, 0, 0, 1, 1.0, 101}, Case{4000, 0, 0, 2, 1.0, 102},
                      Case{4000, 0, 0, 3, 1.0, 103}, Case{4000, 0, 0, 4, 1.0, 104},
                      Case{4000, 0, 0, 5, 1.0, 105}, Case{4000, 0, 0, 6, 1.0, 106},
                      Case{4000, 0, 0, 7, 1.0, 107}, Case{4000, 0, 0, 8, 1.0, 108},
                      Case{4000, 0, 0, 9, 1.0, 109}, Case{4000, 0, 0, 10, 1.0, 110},
                      Case{4000, 0, 0, 11, 1.0, 111}, Case{4000, 0, 0, 12, 1.0, 112},
                      Case{4000, 0, 0, 13, 1.0, 113}, Case{4000, 0, 0, 14, 1.0, 114},
                      Case{4000, 0, 0, 15, 1.0, 115}, Case{4000, 0, 0, 16, 1.0, 116}),
    case_name);

TEST(CoresetTest, ColumnsOfVeryDifferentScales) {
  // Each coordinate is scaled on its own, so columns 12 orders of magnitude apart stay exact.
  Rows rows = random_rows(30000, 6, 1.0, 23);
  const double column_scale[6] = {1e-6, 1.0, 1e6, 1e-3, 1e3, 1.0};
  for (int c = 0; c < 6; ++c) rows.J.col(c) *= column_scale[c];
  rows.e *= 1e-4;
  const RowCoreset coreset = select_coreset_rows(rows.J, rows.e);
  EXPECT_EQ(coreset.rows.size(), 29u);
  EXPECT_LE(coreset_error(rows, coreset).max(), 1e-12);
}

TEST(CoresetTest, ZeroResidualsGiveZeroGradientAndCost) {
  Rows rows = random_rows(5000, 6, 1.0, 24);
  rows.e.setZero();
  const RowCoreset coreset = select_coreset_rows(rows.J, rows.e);
  const QuadraticModel reference = quadratic_model(rows.J, rows.e);
  const QuadraticModel approx = quadratic_model(rows.J, rows.e, coreset.rows, coreset.weights);
  EXPECT_EQ(reference.c, 0.0);
  EXPECT_EQ(approx.c, 0.0);
  EXPECT_EQ(approx.b.norm(), 0.0);
  // The relative error falls back to the absolute one where the reference is zero.
  const QuadraticModelError err = relative_error(reference, approx);
  EXPECT_EQ(err.b, 0.0);
  EXPECT_EQ(err.c, 0.0);
  EXPECT_LE(err.H, 1e-12);
}

TEST(CoresetTest, InexactSizeReturnsAtMostTheTarget) {
  const Rows rows = random_rows(30000, 6, 1.0, 25);
  for (int target : {29, 100, 1000}) {
    RowCoresetOptions options;
    options.target_rows = target;
    options.exact_size = false;
    const RowCoreset coreset = select_coreset_rows(rows.J, rows.e, options);
    EXPECT_LE(coreset.rows.size(), static_cast<std::size_t>(target));
    EXPECT_GE(coreset.rows.size(), 1u);
    EXPECT_LE(coreset_error(rows, coreset).max(), 1e-12) << target;
  }
}

TEST(CoresetTest, DegenerateData) {
  // Rank-deficient J (a repeated column and a zero column), e = 0, and outliers.
  Rows rows = random_rows(20000, 6, 1.0, 21);
  rows.J.col(3) = rows.J.col(1);
  rows.J.col(5).setZero();
  for (bool zero_e : {false, true}) {
    Rows data = rows;
    if (zero_e) data.e.setZero();
    const RowCoreset coreset = select_coreset_rows(data.J, data.e);
    EXPECT_EQ(coreset.rows.size(), 29u) << "exact size even when fewer rows would do";
    const QuadraticModelError err = coreset_error(data, coreset);
    EXPECT_LE(err.max(), 1e-12) << "zero_e=" << zero_e;
    if (zero_e) {
      RowCoresetOptions loose;
      loose.exact_size = false;
      const RowCoreset small = select_coreset_rows(data.J, data.e, loose);
      EXPECT_LE(small.rows.size(), 29u);
      EXPECT_LE(coreset_error(data, small).max(), 1e-12);
    }
  }
  Rows outliers = random_rows(20000, 6, 1.0, 22);
  for (int k = 0; k < 20; ++k) {
    outliers.J.row(k * 997) *= 1e5;
    outliers.e[k * 991] = 1e6;
  }
  EXPECT_LE(coreset_error(outliers, select_coreset_rows(outliers.J, outliers.e)).max(), 1e-12);
}

TEST(CoresetTest, FewRowsComeBackWhole) {
  const Rows rows = random_rows(20, 6, 1.0, 3);
  const RowCoreset coreset = select_coreset_rows(rows.J, rows.e);
  ASSERT_EQ(coreset.rows.size(), 20u);
  for (std::size_t k = 0; k < 20; ++k) {
    EXPECT_EQ(coreset.rows[k], static_cast<int>(k));
    EXPECT_EQ(coreset.weights[k], 1.0);
  }
}

TEST(CoresetTest, SameSeedSameResult) {
  const Rows rows = random_rows(30000, 6, 1.0, 4);
  RowCoresetOptions options;
  options.seed = 77;
  const RowCoreset a = select_coreset_rows(rows.J, rows.e, options);
  const RowCoreset b = select_coreset_rows(rows.J, rows.e, options);
  EXPECT_EQ(a.rows, b.rows);
  EXPECT_EQ(a.weights, b.weights);
  options.seed = 78;
  const RowCoreset c = select_coreset_rows(rows.J, rows.e, options);
  EXPECT_NE(a.rows, c.rows);
  EXPECT_LE(coreset_error(rows, c).max(), 1e-12);
}

TEST(CoresetTest, BadInputIsAClearError) {
  Rows rows = random_rows(500, 6, 1.0, 5);
  RowCoresetOptions options;
  options.target_rows = 20;
  expect_error([&] { select_coreset_rows(rows.J, rows.e, options); },
               "coreset: target of 20 rows is below the minimum of 29 for reduced dimension 6");
  options = {};
  options.clusters = 20;
  expect_error([&] { select_coreset_rows(rows.J, rows.e, options); },
               "coreset: 20 clusters cannot make progress for reduced dimension 6 (lifted "
               "dimension 28); use at least 30");
  rows.J(123, 2) = std::nan("");
  expect_error([&] { select_coreset_rows(rows.J, rows.e); },
               "coreset: row 123 has a non-finite residual or Jacobian entry");
  rows.J(123, 2) = 0.0;
  rows.e[400] = std::numeric_limits<double>::infinity();
  expect_error([&] { select_coreset_rows(rows.J, rows.e); },
               "coreset: row 400 has a non-finite residual or Jacobian entry");
  options = {};
  options.target_rows = -3;
  expect_error([&] { select_coreset_rows(rows.J, rows.e, options); },
               "coreset: target of -3 rows is negative");
  rows.e[400] = 1e300;
  expect_error([&] { select_coreset_rows(rows.J, rows.e); }, "overflow when squared");
  rows.e[400] = 0.0;
  // N <= M still checks the rows: no silent pass-through of NaN.
  Rows few = random_rows(10, 6, 1.0, 6);
  few.e[7] = std::nan("");
  expect_error([&] { select_coreset_rows(few.J, few.e); },
               "coreset: row 7 has a non-finite residual or Jacobian entry");
  const Eigen::VectorXd short_e = Eigen::VectorXd::Zero(10);
  expect_error([&] { select_coreset_rows(rows.J, short_e); },
               "coreset: 500 Jacobian rows but 10 residuals");
  // A dimension whose coreset would not fit (20,000 rows lifted to 13,041 numbers each, and
  // eliminations of 20,000 points): refused before any allocation.
  Rows wide = random_rows(20000, 160, 1.0, 7);
  expect_error([&] { select_coreset_rows(wide.J, wide.e); },
               "coreset: reduced dimension 160 (lifted dimension 13041) with 26084 clusters needs "
               "about");
  // Fewer rows than the minimum target are returned whole, whatever the dimension.
  EXPECT_EQ(select_coreset_rows(wide.J.topRows(400), wide.e.head(400)).rows.size(), 400u);
  // The default clusters follow the dimension: D = 12 works without setting them.
  Rows twelve = random_rows(3000, 12, 1.0, 8);
  const RowCoreset coreset = select_coreset_rows(twelve.J, twelve.e);
  EXPECT_EQ(coreset.rows.size(), 92u);
  EXPECT_EQ(default_coreset_clusters(12), 184);
  EXPECT_EQ(default_coreset_clusters(6), 64);
}

}  // namespace
}  // namespace carat
