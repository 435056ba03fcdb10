// The package's surface: the version the build reports and the umbrella header.
#include <gtest/gtest.h>

#include <carat/carat.hpp>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>

namespace carat {
namespace {

/// Whether text is MAJOR.MINOR.PATCH (three non-empty runs of digits).
bool is_semantic_version(const std::string& text) {
  int parts = 1;
  bool digits = false;
  for (char c : text) {
    if (c == '.') {
      if (!digits) return false;
      ++parts;
      digits = false;
    } else if (c >= '0' && c <= '9') {
      digits = true;
    } else {
      return false;
    }
  }
  return digits && parts == 3;
}

TEST(PackageTest, VersionIsTheProjectVersion) {
  EXPECT_STREQ(version(), CARAT_PROJECT_VERSION);
  EXPECT_TRUE(is_semantic_version(version())) << version();
  EXPECT_FALSE(is_semantic_version("1.2"));
  EXPECT_FALSE(is_semantic_version("1..2"));
}

TEST(PackageTest, UmbrellaHeaderIncludesEveryPublicHeader) {
  const std::filesystem::path source(CARAT_SOURCE_DIR);
  std::set<std::string> expected;
  for (const char* module : {"base", "solver", "coreset", "residuals", "registration", "sim"}) {
    const std::filesystem::path folder = source / module / "include" / "carat" / module;
    for (const auto& entry : std::filesystem::recursive_directory_iterator(folder)) {
      if (entry.path().extension() == ".hpp") {
        const std::string relative = entry.path().lexically_relative(folder).generic_string();
        expected.insert(std::string("carat/") + module + "/" + relative);
      }
    }
  }
  ASSERT_GT(expected.size(), 40u);
  std::ifstream umbrella(source / "include" / "carat" / "carat.hpp");
  ASSERT_TRUE(umbrella.good());
  std::set<std::string> included;  // "carat/<module>/[io/]<name>.hpp" of each #include <...> line
  const std::string open = "#include <";
  std::string line;
  while (std::getline(umbrella, line)) {
    if (line.rfind(open + "carat/", 0) == 0 && line.back() == '>') {
      included.insert(line.substr(open.size(), line.size() - open.size() - 1));
    }
  }
  for (const std::string& header : expected) {
    EXPECT_TRUE(included.count(header)) << header << " is missing from carat/carat.hpp";
  }
  for (const std::string& header : included) {
    EXPECT_TRUE(expected.count(header)) << header << " is in carat/carat.hpp but does not exist";
  }
}

}  // namespace
}  // namespace carat
