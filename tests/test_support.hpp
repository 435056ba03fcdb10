#pragma once

// Helpers shared by carat's tests.

#include <Eigen/Geometry>
#include <filesystem>
#include <functional>
#include <random>
#include <string>

#include "carat/base/error.hpp"
#include "carat/solver/se3.hpp"

namespace carat::test {

/// The real-data folder (../shared/data), which may be absent.
std::filesystem::path data_dir();

/// True if `relative` exists under data_dir().
bool has_data(const std::string& relative);

/// A fresh, empty scratch directory for one test.
std::filesystem::path scratch_dir(const std::string& name);

/// The message of the carat::Error that `f` throws, or "(no error)" when it throws none.
inline std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

/// A random pose Exp(xi): rotation vector ~ N(0, rotation^2) per axis (radians), translation
/// ~ N(0, shift^2) per axis (metres).
inline Eigen::Isometry3d random_pose(std::mt19937_64& rng, double rotation = 1.0,
                                     double shift = 3.0) {
  std::normal_distribution<double> n;
  se3::Vector6d xi;
  for (int k = 0; k < 3; ++k) xi[k] = rotation * n(rng);
  for (int k = 3; k < 6; ++k) xi[k] = shift * n(rng);
  return se3::exp(xi);
}

}  // namespace carat::test

/// Skips the current test when a real-data file or folder is absent.
#define CARAT_REQUIRE_DATA(relative)                                    \
  do {                                                                  \
    if (!::carat::test::has_data(relative)) {                           \
      GTEST_SKIP() << "real data " << (relative) << " not found under " \
                   << ::carat::test::data_dir();                        \
    }                                                                   \
  } while (0)
