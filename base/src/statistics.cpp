#include "carat/base/statistics.hpp"

#include <algorithm>
#include <cstddef>
#include <vector>

#include "carat/base/error.hpp"

namespace carat {

double median(std::span<const double> values) {
  if (values.empty()) throw Error("median: no values");
  std::vector<double> v(values.begin(), values.end());
  const std::size_t middle = v.size() / 2;
  const auto upper = v.begin() + static_cast<std::ptrdiff_t>(middle);
  std::nth_element(v.begin(), upper, v.end());
  if (v.size() % 2 == 1) return *upper;
  // Below the middle lie the smaller half: its largest is the lower middle value.
  const double lower = *std::max_element(v.begin(), upper);
  return 0.5 * (lower + *upper);
}

}  // namespace carat
