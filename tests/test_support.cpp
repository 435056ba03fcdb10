#include "test_support.hpp"

#include <cstdlib>

namespace carat::test {

std::filesystem::path data_dir() {
  if (const char* env = std::getenv("CARAT_DATA_DIR")) return env;
  return CARAT_DATA_DIR;
}

bool has_data(const std::string& relative) {
  std::error_code ec;
  return std::filesystem::exists(data_dir() / relative, ec);
}

std::filesystem::path scratch_dir(const std::string& name) {
  const auto dir = std::filesystem::path(CARAT_BINARY_DIR) / "test_scratch" / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace carat::test
