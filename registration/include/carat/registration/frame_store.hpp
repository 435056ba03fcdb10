#pragma once

/// Frames by index, either all held in memory or read and preprocessed on demand and kept in a
/// least-recently-used cache under a byte cap, so that a map larger than memory can be built.

#include <condition_variable>
#include <cstddef>
#include <functional>
#include <list>
#include <memory>
#include <mutex>
#include <span>
#include <vector>

#include "carat/registration/frame.hpp"

namespace carat {

/// What a FrameStore did so far.
struct FrameStoreStats {
  std::size_t requests = 0;     ///< get() calls
  std::size_t hits = 0;         ///< get() calls served from memory
  std::size_t loads = 0;        ///< frames read and preprocessed (the loader's calls)
  std::size_t evictions = 0;    ///< frames dropped from the cache to stay under the cap
  std::size_t peak_bytes = 0;   ///< largest bytes of frames held at once (Frame::memory_bytes())
  std::size_t max_bytes = 0;    ///< the cap (0: none)
  std::size_t point_loads = 0;  ///< frames read for their points alone (the points loader's calls)
};

/// Frames 0 .. size()-1 for the registration pipeline. Thread-safe: any thread may call get().
class FrameStore {
 public:
  /// Reads and preprocesses frame k (called from any thread, at most once at a time per frame);
  /// throws carat::Error naming the frame when it cannot.
  using Loader = std::function<std::shared_ptr<const Frame>(std::size_t)>;
  /// Reads frame k's points alone, as the Loader's frame would hold them (frame coordinates,
  /// downsampled; covariances not needed), from any thread; throws carat::Error naming the frame
  /// when it cannot.
  using PointsLoader = std::function<PointCloud(std::size_t)>;

  /// Every frame already in memory; nothing is loaded or evicted. Throws carat::Error for a
  /// null frame.
  explicit FrameStore(std::vector<std::shared_ptr<const Frame>> frames);
  /// `count` frames that `load` provides on demand, at most `max_bytes` of them cached (frames
  /// in use by a caller stay and count; the least recently used others are dropped first).
  /// max_bytes = 0: no cap, every frame is loaded once and kept.
  FrameStore(std::size_t count, Loader load, std::size_t max_bytes);
  /// As above, with `load_points` to serve points() for frames not in memory without building
  /// them (no covariances, no tree: a fraction of a frame's preprocessing).
  FrameStore(std::size_t count, Loader load, PointsLoader load_points, std::size_t max_bytes);
  FrameStore(const FrameStore&) = delete;
  FrameStore& operator=(const FrameStore&) = delete;

  /// Number of frames.
  std::size_t size() const { return entries_.size(); }
  /// Frame k, loaded if it is not in memory. Throws carat::Error for k out of range, or what the
  /// loader threw (a later get() of the same frame tries again).
  std::shared_ptr<const Frame> get(std::size_t k);
  /// Reads frame k into the cache unless it is there or being read already, and returns at once
  /// in those cases: a worker that knows which frames come next reads them while the others
  /// work, instead of all waiting for the same frame later. Returns whether this call read it.
  /// Not a request: stats() counts its reads as loads only. A loader error is dropped (the
  /// frame stays unread, and the next get() tries again and throws it); so is k out of range.
  bool prefetch(std::size_t k);
  /// Frame k's points (frame coordinates), for a caller that needs nothing else, such as an
  /// overlap test: the cached frame's cloud when frame k is in memory, else read with the points
  /// loader and not kept (its covariances may then be absent), else get(k)'s. Not a request:
  /// stats() counts the points loader's reads as point_loads. Throws as get(k) does.
  std::shared_ptr<const PointCloud> points(std::size_t k);
  /// True when the frames are held in memory by the caller (the first constructor).
  bool resident() const { return !load_; }
  /// Drops every cached frame that no caller holds, when frames are read on demand (a later
  /// get() reads it again); a resident store keeps its frames. For a pipeline done with its
  /// frames, such as the solve after the last round of factors.
  void release_cached();
  /// Counts so far.
  FrameStoreStats stats() const;
  /// Points of each frame as last given or loaded (0: not loaded yet), indexed by frame.
  std::vector<std::size_t> frame_points() const;

 private:
  struct Entry {
    std::shared_ptr<const Frame> frame;
    std::size_t bytes = 0;
    std::size_t points = 0;  // of the frame as last loaded
    bool loading = false;
    std::list<std::size_t>::iterator lru;  // valid while frame is set
  };
  void evict_locked(std::size_t incoming);  // drops frames until `incoming` more bytes fit
  // Reads entry k, marked as loading by the caller, with `lock` released meanwhile; throws what
  // the loader threw (the mark cleared).
  std::shared_ptr<const Frame> load_marked(std::size_t k, std::unique_lock<std::mutex>& lock);

  std::vector<Entry> entries_;
  Loader load_;
  PointsLoader load_points_;
  std::size_t max_bytes_ = 0;
  std::size_t bytes_ = 0;
  std::list<std::size_t> lru_;  // cached frames, most recently used first
  FrameStoreStats stats_;
  mutable std::mutex mutex_;
  std::condition_variable loaded_;
};

/// Frames the caller holds as a resident store; throws as FrameStore's constructor does. What the
/// deprecated overloads that take a span of frames do.
inline FrameStore resident_store(std::span<const std::shared_ptr<const Frame>> frames) {
  return FrameStore(std::vector<std::shared_ptr<const Frame>>(frames.begin(), frames.end()));
}

}  // namespace carat
