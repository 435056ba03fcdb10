#pragma once

// Shared helpers of the coreset tests: random rows, coreset error, exact error messages.

#include <gtest/gtest.h>

#include <functional>
#include <random>
#include <string>

#include "carat/base/error.hpp"
#include "carat/coreset/quadratic_model.hpp"
#include "carat/coreset/row_coreset.hpp"

namespace carat::test {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

struct Rows {
  RowMatrix J;
  Eigen::VectorXd e;
};

inline Rows random_rows(long n, int d, double scale, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  Rows rows{RowMatrix(n, d), Eigen::VectorXd(n)};
  for (long i = 0; i < rows.J.size(); ++i) rows.J.data()[i] = scale * normal(rng);
  for (long i = 0; i < n; ++i) rows.e[i] = scale * normal(rng);
  return rows;
}

inline QuadraticModelError coreset_error(const Rows& rows, const RowCoreset& coreset) {
  return relative_error(quadratic_model(rows.J, rows.e),
                        quadratic_model(rows.J, rows.e, coreset.rows, coreset.weights));
}

/// Runs f and expects a carat::Error whose message contains `message`.
inline void expect_error(const std::function<void()>& f, const std::string& message) {
  try {
    f();
    FAIL() << "expected: " << message;
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(message), std::string::npos)
        << "message: " << e.what() << "\nexpected to contain: " << message;
  }
}

}  // namespace carat::test
