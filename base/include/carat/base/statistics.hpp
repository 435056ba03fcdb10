#pragma once

/// Summary statistics of a set of numbers.

#include <span>

namespace carat {

/// The median of `values`: the middle value of an odd count, the mean of the two middle values
/// of an even count (in the values' own units). `values` need not be sorted and is not modified.
/// Throws carat::Error for an empty set; NaN values give an unspecified result.
double median(std::span<const double> values);

}  // namespace carat
