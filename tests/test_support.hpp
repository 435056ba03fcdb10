#pragma once

// Helpers shared by carat's tests.

#include <filesystem>
#include <functional>
#include <string>

#include "carat/base/error.hpp"

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

}  // namespace carat::test

/// Skips the current test when a real-data file or folder is absent.
#define CARAT_REQUIRE_DATA(relative)                                    \
  do {                                                                  \
    if (!::carat::test::has_data(relative)) {                           \
      GTEST_SKIP() << "real data " << (relative) << " not found under " \
                   << ::carat::test::data_dir();                        \
    }                                                                   \
  } while (0)
