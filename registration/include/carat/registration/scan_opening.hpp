#pragma once

/// Opening a folder's scans as frames: each scan read, checked (enough points as read, and, on
/// request, geometry that fixes all 6 directions) and preprocessed, either all at once or on
/// demand under a memory cap. The one way `carat map`, `carat odometry`, the MPI ranks and
/// Python's load_frames turn scan files into frames.

#include <cstddef>
#include <functional>
#include <memory>
#include <vector>

#include "carat/registration/frame.hpp"
#include "carat/registration/frame_store.hpp"
#include "carat/registration/io/point_cloud_io.hpp"
#include "carat/registration/io/scan_folder.hpp"

namespace carat {

/// How open_scans() reads, checks and keeps the scans.
struct OpenScansOptions {
  ReadOptions read;              ///< how each file is read (e.g. dropping non-finite points)
  PreprocessOptions preprocess;  ///< downsampling and covariances; min_points also applies to
                                 ///< each scan as read, before downsampling merges any points
  /// 0: every scan is read now, in parallel, and kept; otherwise scans are read on demand and
  /// at most this many bytes of frames (Frame::memory_bytes()) stay cached (SIZE_MAX: on
  /// demand, each kept once read).
  std::size_t max_bytes = 0;
  /// A frame whose geometry fixes fewer than 6 directions (Frame::constrained_dof(), e.g. a
  /// single plane) is an error: its pose cannot be found by registration. Odometry, which
  /// reports such steps itself, turns this off.
  bool require_constrained = true;
  int num_threads = 1;  ///< threads over scans when every scan is read now
};

/// Reads scan `file` and checks that it holds at least `min_points` points. Throws carat::Error
/// naming the file ("DIR/000003.bin: only 12 points (at least 29 are needed)") or as the
/// readers do.
PointCloud read_scan_checked(const ScanFile& file, const ReadOptions& options, int min_points);

/// Preprocesses a scan read from `file` into a frame and checks its geometry when
/// `require_constrained`; throws carat::Error naming the file ("...: the scan fixes only 5 of 6
/// degrees of freedom (a degenerate scene, e.g. a single plane), ...").
std::shared_ptr<const Frame> open_scan(const ScanFile& file, const OpenScansOptions& options);

/// The scans as frames 0 .. files.size()-1 in a FrameStore: resident when options.max_bytes is
/// 0 (every scan read and checked now; `progress` gets (scans done, scans)), else read on
/// demand under the cap (checked as each is read; FrameStore::points() reads a scan's points
/// alone, without the degenerate-geometry check, which the frame's own read makes). Throws
/// carat::Error for no scans, bad options, or the first scan (in order) that cannot be read or
/// fails a check.
std::shared_ptr<FrameStore> open_scans(
    std::vector<ScanFile> files, const OpenScansOptions& options,
    const std::function<void(std::size_t, std::size_t)>& progress = {});

}  // namespace carat
