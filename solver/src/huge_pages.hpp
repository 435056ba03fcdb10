#pragma once

// Internal: large, freshly allocated buffers backed by transparent huge pages where the kernel
// offers them (Linux with THP in "madvise" or "always" mode; a no-op elsewhere).
//
// Why: the first touch of every 4 KiB page is a page fault, and on virtual machines a fault is
// expensive (measured on the 2-core VM carat is benchmarked on: ~12 us per fault, 62 ms to first
// touch 21 MB, 13-23 ms with huge pages). A solve touches its factor, matrix and per-block
// buffers for the first time in the symbolic analysis and the first iteration, where this was
// up to a fifth of a pose-graph solve's total time. The kernel backs only 2 MiB-aligned 2 MiB
// ranges with a huge page, so a buffer gains fully only if it is itself 2 MiB-aligned: the
// allocator below gives large buffers that alignment.

#include <cstddef>
#include <vector>

namespace carat::internal {

/// Advises the kernel to back the whole pages inside [data, data + bytes) with huge pages.
/// Only useful before the pages are first touched; buffers under 2 MiB are left alone.
void advise_huge_pages(void* data, std::size_t bytes);

/// Storage of `bytes` bytes: from 1 MiB on, whole 2 MiB-aligned huge pages advised as above;
/// below, plain operator new.
void* allocate_huge(std::size_t bytes);

/// Releases storage from allocate_huge(bytes) (the same byte count).
void deallocate_huge(void* data, std::size_t bytes) noexcept;

/// An allocator whose large allocations come from allocate_huge.
template <class T>
struct HugePageAllocator {
  using value_type = T;  ///< element type

  /// Stateless: nothing to set up.
  HugePageAllocator() = default;
  /// Rebinding copy (stateless).
  template <class U>
  HugePageAllocator(const HugePageAllocator<U>&) noexcept {}
  /// Storage for n elements.
  T* allocate(std::size_t n) { return static_cast<T*>(allocate_huge(n * sizeof(T))); }
  /// Releases storage for n elements.
  void deallocate(T* p, std::size_t n) noexcept { deallocate_huge(p, n * sizeof(T)); }
  /// Stateless: all instances are interchangeable.
  friend bool operator==(const HugePageAllocator&, const HugePageAllocator&) { return true; }
};

/// A vector whose storage, from 1 MiB on, lies on huge pages.
template <class T>
using HugeVector = std::vector<T, HugePageAllocator<T>>;

}  // namespace carat::internal
