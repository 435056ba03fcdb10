// median(): odd and even counts, one value, no values, unsorted input left as it was, and
// agreement with sorting on random sets.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/base/statistics.hpp"
#include "test_support.hpp"

namespace carat {
namespace {

TEST(MedianTest, AnOddCountGivesTheMiddleValue) {
  EXPECT_EQ(median(std::vector<double>{5.0, 1.0, 3.0}), 3.0);
  EXPECT_EQ(median(std::vector<double>{-2.0, 8.0, 8.0, 0.5, 100.0}), 8.0);
}

TEST(MedianTest, AnEvenCountGivesTheMeanOfTheTwoMiddleValues) {
  EXPECT_EQ(median(std::vector<double>{4.0, 1.0, 3.0, 2.0}), 2.5);
  EXPECT_EQ(median(std::vector<double>{100.0, 1.0}), 50.5);
  EXPECT_EQ(median(std::vector<double>{2.0, 7.0, 2.0, 2.0}), 2.0);
}

TEST(MedianTest, OneValueIsItsOwnMedian) { EXPECT_EQ(median(std::vector<double>{-7.25}), -7.25); }

TEST(MedianTest, NoValuesIsAnError) {
  EXPECT_EQ(test::error_of([] { median(std::vector<double>{}); }), "median: no values");
}

TEST(MedianTest, UnsortedInputIsNotModified) {
  const std::vector<double> original{9.0, 2.0, 7.0, 4.0, 5.0, 1.0};
  std::vector<double> values = original;
  EXPECT_EQ(median(values), 4.5);
  EXPECT_EQ(values, original);
}

TEST(MedianTest, AgreesWithSortingOnRandomSets) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> uniform(-1e3, 1e3);
  for (std::size_t n = 1; n <= 40; ++n) {
    std::vector<double> values(n);
    for (double& v : values) v = uniform(rng);
    std::vector<double> sorted = values;
    std::sort(sorted.begin(), sorted.end());
    const double expected = n % 2 == 1 ? sorted[n / 2] : 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]);
    EXPECT_EQ(median(values), expected) << n << " values";
  }
}

}  // namespace
}  // namespace carat
