#pragma once

// Helpers shared by carat's tests.

#include <filesystem>
#include <string>

namespace carat::test {

/// The real-data folder (../shared/data), which may be absent.
std::filesystem::path data_dir();

/// True if `relative` exists under data_dir().
bool has_data(const std::string& relative);

/// A fresh, empty scratch directory for one test.
std::filesystem::path scratch_dir(const std::string& name);

}  // namespace carat::test

/// Skips the current test when a real-data file or folder is absent.
#define CARAT_REQUIRE_DATA(relative)                                    \
  do {                                                                  \
    if (!::carat::test::has_data(relative)) {                           \
      GTEST_SKIP() << "real data " << (relative) << " not found under " \
                   << ::carat::test::data_dir();                        \
    }                                                                   \
  } while (0)
