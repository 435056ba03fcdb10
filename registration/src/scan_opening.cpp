#include "carat/registration/scan_opening.hpp"

#include <string>
#include <utility>

#include "carat/base/error.hpp"

namespace carat {
namespace {

/// Throws for a frame whose own geometry cannot fix its pose.
void check_constrained(const Frame& frame) {
  if (frame.constrained_dof() < 6) {
    throw Error(frame.name() + ": the scan fixes only " + std::to_string(frame.constrained_dof()) +
                " of 6 degrees of freedom (a degenerate scene, e.g. a single plane), so its pose "
                "cannot be determined by registration");
  }
}

}  // namespace

PointCloud read_scan_checked(const ScanFile& file, const ReadOptions& options, int min_points) {
  PointCloud scan = read_scan(file, options);
  if (scan.size() < static_cast<std::size_t>(min_points)) {
    throw Error(file.path.string() + ": only " + std::to_string(scan.size()) +
                " points (at least " + std::to_string(min_points) + " are needed)");
  }
  return scan;
}

std::shared_ptr<const Frame> open_scan(const ScanFile& file, const OpenScansOptions& options) {
  auto frame =
      preprocess_frame(read_scan_checked(file, options.read, options.preprocess.min_points),
                       options.preprocess, file.path.string());
  if (options.require_constrained) check_constrained(*frame);
  return frame;
}

std::shared_ptr<FrameStore> open_scans(
    std::vector<ScanFile> files, const OpenScansOptions& options,
    const std::function<void(std::size_t, std::size_t)>& progress) {
  if (files.empty()) throw Error("open scans: no scans given");
  if (options.num_threads < 1) {
    throw Error("open scans: num_threads must be >= 1, got " + std::to_string(options.num_threads));
  }
  if (options.max_bytes == 0) {
    std::vector<std::shared_ptr<const Frame>> frames = preprocess_frames(
        files.size(),
        [&](std::size_t k) {
          return read_scan_checked(files[k], options.read, options.preprocess.min_points);
        },
        [&](std::size_t k) { return files[k].path.string(); }, options.preprocess,
        options.num_threads, progress);
    if (options.require_constrained) {
      for (const auto& frame : frames) check_constrained(*frame);
    }
    return std::make_shared<FrameStore>(std::move(frames));
  }
  return std::make_shared<FrameStore>(
      files.size(), [files, options](std::size_t k) { return open_scan(files[k], options); },
      [files, options](std::size_t k) {
        return downsample_frame_points(
            read_scan_checked(files[k], options.read, options.preprocess.min_points),
            options.preprocess, files[k].path.string());
      },
      options.max_bytes);
}

}  // namespace carat
