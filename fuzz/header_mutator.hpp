#pragma once

// A header-aware libFuzzer mutation for text headers followed by data (PCD, PLY): half of the
// mutations replace one number of the header (the text before `end_marker`) by a boundary value
// -- 0, 2^31, 2^32, 2^62, 2^63, 2^64 - 1, 2^64, or 2^64 / k - j for field sizes k, which makes a
// product SIZE x COUNT wrap to -k j -- the other half are libFuzzer's own. Byte
// mutations alone rarely build a header whose numbers are consistent and wrap (the class of bug
// where a wrapped record size lets a reader index past its buffer).

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <random>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

extern "C" std::size_t LLVMFuzzerMutate(std::uint8_t* data, std::size_t size, std::size_t max_size);

namespace carat::fuzz {

/// Replaces one header number of `data` by a boundary value, or lets libFuzzer mutate.
inline std::size_t mutate_header_number(std::uint8_t* data, std::size_t size, std::size_t max_size,
                                        unsigned seed, std::string_view end_marker) {
  std::mt19937 rng(seed);
  if (rng() % 2 == 0) return LLVMFuzzerMutate(data, size, max_size);
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const std::size_t header_end = std::min(text.find(end_marker), size);
  std::vector<std::pair<std::size_t, std::size_t>> numbers;  // [begin, end) of digit runs
  for (std::size_t i = 0; i < header_end;) {
    if (text[i] >= '0' && text[i] <= '9') {
      const std::size_t begin = i;
      while (i < header_end && text[i] >= '0' && text[i] <= '9') ++i;
      numbers.emplace_back(begin, i);
    } else {
      ++i;
    }
  }
  if (numbers.empty()) return LLVMFuzzerMutate(data, size, max_size);
  static const char* const kFixed[] = {"0",
                                       "1",
                                       "2147483648",
                                       "4294967295",
                                       "4294967296",
                                       "4611686018427387904",
                                       "9223372036854775807",
                                       "9223372036854775808",
                                       "18446744073709551615",
                                       "18446744073709551616"};
  std::string value;
  if (rng() % 2 == 0) {
    value = kFixed[rng() % (sizeof(kFixed) / sizeof(kFixed[0]))];
  } else {
    // 2^64 / k - j: times a field size k the product wraps to -k j, so a later field's offset
    // is huge while the record (the sum) wraps to a few bytes.
    static const unsigned kSizes[] = {1, 2, 3, 4, 6, 8, 12, 16, 24, 32};
    const unsigned k = kSizes[rng() % (sizeof(kSizes) / sizeof(kSizes[0]))];
    const unsigned __int128 wrap = (static_cast<unsigned __int128>(1) << 64) / k;
    value = std::to_string(static_cast<std::uint64_t>(wrap - rng() % 17));
  }
  const auto [begin, end] = numbers[rng() % numbers.size()];
  const std::size_t new_size = size - (end - begin) + value.size();
  if (new_size > max_size) return LLVMFuzzerMutate(data, size, max_size);
  std::memmove(data + begin + value.size(), data + end, size - end);
  std::memcpy(data + begin, value.data(), value.size());
  return new_size;
}

}  // namespace carat::fuzz
