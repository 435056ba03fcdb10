#pragma once

// Internal: large, freshly allocated buffers backed by transparent huge pages where the kernel
// offers them (Linux with THP in "madvise" or "always" mode; a no-op elsewhere).
//
// Why: the first touch of every 4 KiB page is a page fault, and on virtual machines a fault is
// expensive (measured on the 2-core VM carat is benchmarked on: ~12 us per fault, 62 ms to first
// touch 21 MB, 13-23 ms with huge pages). A solve touches its factor, matrix and per-block
// buffers for the first time in the symbolic analysis and the first iteration, where this was
// up to a fifth of a pose-graph solve's total time.

#include <cstddef>
#include <vector>

namespace carat::internal {

/// Advises the kernel to back the whole pages inside [data, data + bytes) with huge pages.
/// Only useful before the pages are first touched; buffers under 2 MiB are left alone.
void advise_huge_pages(void* data, std::size_t bytes);

/// v = n copies of value, in fresh storage advised as above (for buffers of 2 MiB and more).
template <class T>
void assign_on_huge_pages(std::vector<T>& v, std::size_t n, const T& value) {
  std::vector<T>().swap(v);  // release the old storage so the new one is fresh
  v.reserve(n);
  advise_huge_pages(v.data(), n * sizeof(T));
  v.assign(n, value);
}

}  // namespace carat::internal
