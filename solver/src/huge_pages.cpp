#include "huge_pages.hpp"

#include <cstdint>
#include <new>

#if defined(__linux__)
#include <sys/mman.h>
#include <unistd.h>
#endif

namespace carat::internal {
namespace {

constexpr std::size_t kHugePage = std::size_t{2} << 20;
/// From this size on, allocate_huge rounds up to whole huge pages (at most 2x the memory, and
/// one fault instead of up to 512).
constexpr std::size_t kHugeFrom = std::size_t{1} << 20;

}  // namespace

void advise_huge_pages(void* data, std::size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  if (data == nullptr || bytes < kHugePage) return;
  static const long page_size = sysconf(_SC_PAGESIZE);
  if (page_size <= 0) return;
  const auto kPage = static_cast<std::uintptr_t>(page_size);
  const auto begin = reinterpret_cast<std::uintptr_t>(data);
  const std::uintptr_t first = (begin + kPage - 1) & ~(kPage - 1);
  const std::uintptr_t last = (begin + bytes) & ~(kPage - 1);
  // Advice only: if the kernel refuses (THP off, old kernel), the buffer keeps small pages.
  if (last > first) (void)madvise(reinterpret_cast<void*>(first), last - first, MADV_HUGEPAGE);
#else
  (void)data;
  (void)bytes;
#endif
}

void* allocate_huge(std::size_t bytes) {
  if (bytes < kHugeFrom) return ::operator new(bytes);
  // Whole huge pages, so that the last one is not shared with another allocation.
  const std::size_t rounded = (bytes + kHugePage - 1) / kHugePage * kHugePage;
  void* data = ::operator new (rounded, std::align_val_t{kHugePage});
  advise_huge_pages(data, rounded);
  return data;
}

void deallocate_huge(void* data, std::size_t bytes) noexcept {
  if (data == nullptr) return;
  if (bytes < kHugeFrom) {
    ::operator delete(data);
    return;
  }
  ::operator delete (data, std::align_val_t{kHugePage});
}

}  // namespace carat::internal
