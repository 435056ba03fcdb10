#include "carat/registration/frame_store.hpp"

#include <malloc.h>

#include <algorithm>
#include <exception>
#include <string>
#include <utility>

#include "carat/base/error.hpp"

namespace carat {

FrameStore::FrameStore(std::vector<std::shared_ptr<const Frame>> frames) : entries_(frames.size()) {
  for (std::size_t k = 0; k < frames.size(); ++k) {
    if (!frames[k]) throw Error("frame store: frame " + std::to_string(k) + " is null");
    entries_[k].bytes = frames[k]->memory_bytes();
    entries_[k].points = frames[k]->size();
    entries_[k].frame = std::move(frames[k]);
    bytes_ += entries_[k].bytes;
  }
  stats_.peak_bytes = bytes_;
}

FrameStore::FrameStore(std::size_t count, Loader load, std::size_t max_bytes)
    : entries_(count), load_(std::move(load)), max_bytes_(max_bytes) {
  if (!load_) throw Error("frame store: no loader given");
  stats_.max_bytes = max_bytes;
}

FrameStore::FrameStore(std::size_t count, Loader load, PointsLoader load_points,
                       std::size_t max_bytes)
    : FrameStore(count, std::move(load), max_bytes) {
  if (!load_points) throw Error("frame store: no points loader given");
  load_points_ = std::move(load_points);
}

std::shared_ptr<const Frame> FrameStore::get(std::size_t k) {
  if (k >= entries_.size()) {
    throw Error("frame store: frame " + std::to_string(k) + " requested of " +
                std::to_string(entries_.size()));
  }
  std::unique_lock lock(mutex_);
  ++stats_.requests;
  Entry& entry = entries_[k];
  if (!load_) {
    ++stats_.hits;
    return entry.frame;
  }
  loaded_.wait(lock, [&] { return !entry.loading; });
  if (entry.frame) {
    ++stats_.hits;
    lru_.splice(lru_.begin(), lru_, entry.lru);
    return entry.frame;
  }
  entry.loading = true;
  return load_marked(k, lock);
}

bool FrameStore::prefetch(std::size_t k) {
  if (!load_ || k >= entries_.size()) return false;
  std::unique_lock lock(mutex_);
  Entry& entry = entries_[k];
  if (entry.frame || entry.loading) return false;
  entry.loading = true;
  try {
    load_marked(k, lock);
  } catch (...) {
    return false;
  }
  return true;
}

std::shared_ptr<const PointCloud> FrameStore::points(std::size_t k) {
  if (k >= entries_.size()) {
    throw Error("frame store: frame " + std::to_string(k) + " requested of " +
                std::to_string(entries_.size()));
  }
  {
    std::lock_guard lock(mutex_);
    const std::shared_ptr<const Frame>& frame = entries_[k].frame;
    if (frame) return std::shared_ptr<const PointCloud>(frame, &frame->cloud());
  }
  if (!load_points_) {
    std::shared_ptr<const Frame> frame = get(k);
    return std::shared_ptr<const PointCloud>(frame, &frame->cloud());
  }
  auto cloud = std::make_shared<const PointCloud>(load_points_(k));
  std::lock_guard lock(mutex_);
  ++stats_.point_loads;
  return cloud;
}

std::shared_ptr<const Frame> FrameStore::load_marked(std::size_t k,
                                                     std::unique_lock<std::mutex>& lock) {
  Entry& entry = entries_[k];
  lock.unlock();
  std::shared_ptr<const Frame> frame;
  try {
    frame = load_(k);
    if (!frame) throw Error("frame store: the loader gave no frame " + std::to_string(k));
  } catch (...) {
    lock.lock();
    entry.loading = false;
    loaded_.notify_all();
    throw;
  }
  const std::size_t bytes = frame->memory_bytes();
  lock.lock();
  evict_locked(bytes);
  entry.loading = false;
  entry.frame = frame;
  entry.bytes = bytes;
  entry.points = frame->size();
  lru_.push_front(k);
  entry.lru = lru_.begin();
  bytes_ += bytes;
  ++stats_.loads;
  stats_.peak_bytes = std::max(stats_.peak_bytes, bytes_);
  loaded_.notify_all();
  return frame;
}

void FrameStore::evict_locked(std::size_t incoming) {
  if (max_bytes_ == 0) return;
  // Least recently used first; a frame some caller still holds stays (it would not free memory).
  for (auto it = lru_.end(); bytes_ + incoming > max_bytes_ && it != lru_.begin();) {
    --it;
    Entry& entry = entries_[*it];
    if (entry.frame.use_count() > 1) continue;
    bytes_ -= entry.bytes;
    entry.frame.reset();
    entry.bytes = 0;
    ++stats_.evictions;
    it = lru_.erase(it);
  }
}

void FrameStore::release_cached() {
  if (!load_) return;
  std::lock_guard lock(mutex_);
  for (auto it = lru_.begin(); it != lru_.end();) {
    Entry& entry = entries_[*it];
    if (entry.frame.use_count() > 1) {
      ++it;
      continue;
    }
    bytes_ -= entry.bytes;
    entry.frame.reset();
    entry.bytes = 0;
    it = lru_.erase(it);
  }
#ifdef __GLIBC__
  // Frames are freed into the malloc arenas of the threads that loaded them, which the caller's
  // next allocations (a solver's, on another thread) would not reuse: return those pages.
  malloc_trim(0);
#endif
}

FrameStoreStats FrameStore::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

std::vector<std::size_t> FrameStore::frame_points() const {
  std::lock_guard lock(mutex_);
  std::vector<std::size_t> out(entries_.size());
  for (std::size_t k = 0; k < entries_.size(); ++k) out[k] = entries_[k].points;
  return out;
}

}  // namespace carat
