// The package's surface: the version the build reports and the umbrella header.
#include <gtest/gtest.h>

#include <carat/carat.hpp>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <string>

namespace carat {
namespace {

TEST(PackageTest, VersionIsTheProjectVersion) {
  EXPECT_STREQ(version(), CARAT_PROJECT_VERSION);
  EXPECT_TRUE(std::regex_match(std::string(version()), std::regex(R"(\d+\.\d+\.\d+)")))
      << version();
}

TEST(PackageTest, UmbrellaHeaderIncludesEveryPublicHeader) {
  const std::filesystem::path source(CARAT_SOURCE_DIR);
  std::set<std::string> expected;
  for (const char* module : {"solver", "coreset", "residuals", "registration"}) {
    const std::filesystem::path folder = source / module / "include" / "carat" / module;
    for (const auto& entry : std::filesystem::directory_iterator(folder)) {
      if (entry.path().extension() == ".hpp") {
        expected.insert(std::string("carat/") + module + "/" + entry.path().filename().string());
      }
    }
  }
  ASSERT_GT(expected.size(), 40u);
  std::ifstream umbrella(source / "include" / "carat" / "carat.hpp");
  ASSERT_TRUE(umbrella.good());
  std::set<std::string> included;
  const std::regex include_line(R"(#include <(carat/[a-z_]+/[a-z_0-9]+\.hpp)>)");
  std::string line;
  while (std::getline(umbrella, line)) {
    std::smatch match;
    if (std::regex_match(line, match, include_line)) included.insert(match[1]);
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
