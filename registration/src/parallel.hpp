#pragma once

// Parallel loops over indices whose errors do not depend on the thread count.

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <exception>
#include <span>
#include <vector>

namespace carat::internal {

/// Runs body(i) for i in [0, n) in parallel; each body runs isolated (a thread waiting inside
/// it on nested TBB work never picks up another index). If bodies throw, the exception of the
/// lowest failing index is rethrown after the loop, whatever the scheduling was; once an index
/// has failed, bodies of higher indices that have not started are skipped (every lower index
/// still runs, so the exception is the same), which ends a failed or interrupted loop early.
template <class Body>
void parallel_for_each_index(std::size_t n, const Body& body) {
  std::vector<std::exception_ptr> errors(n);
  std::atomic<std::size_t> first_failure{n};
  tbb::parallel_for(std::size_t{0}, n, [&](std::size_t i) {
    if (i > first_failure.load(std::memory_order_relaxed)) return;
    try {
      tbb::this_task_arena::isolate([&] { body(i); });
    } catch (...) {
      errors[i] = std::current_exception();
      std::size_t seen = first_failure.load(std::memory_order_relaxed);
      while (i < seen && !first_failure.compare_exchange_weak(seen, i, std::memory_order_relaxed)) {
      }
    }
  });
  for (const std::exception_ptr& error : errors)
    if (error) std::rethrow_exception(error);
}

/// Runs body(order[p]) for every position p of `order`, handing positions out one at a time in
/// order to `threads` workers, so that work started together is neighbouring work in `order`
/// (what a bounded cache of frames needs). Errors as parallel_for_each_index(), by position:
/// the exception of the lowest failing position is rethrown, higher ones are skipped once one
/// failed. Call it inside the task arena that bounds the threads.
template <class Body>
void parallel_for_in_order(std::span<const std::size_t> order, int threads, const Body& body) {
  const std::size_t n = order.size();
  std::vector<std::exception_ptr> errors(n);
  std::atomic<std::size_t> next{0};
  std::atomic<std::size_t> first_failure{n};
  tbb::parallel_for(0, std::max(threads, 1), [&](int) {
    for (std::size_t p = next.fetch_add(1); p < n; p = next.fetch_add(1)) {
      if (p > first_failure.load(std::memory_order_relaxed)) continue;
      try {
        tbb::this_task_arena::isolate([&] { body(order[p]); });
      } catch (...) {
        errors[p] = std::current_exception();
        std::size_t seen = first_failure.load(std::memory_order_relaxed);
        while (p < seen &&
               !first_failure.compare_exchange_weak(seen, p, std::memory_order_relaxed)) {
        }
      }
    }
  });
  for (const std::exception_ptr& error : errors)
    if (error) std::rethrow_exception(error);
}

}  // namespace carat::internal
