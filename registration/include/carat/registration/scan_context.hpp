#pragma once

/// Scan Context (Kim & Kim, IROS 2018): a place descriptor of a LiDAR scan. The plane around the
/// sensor is cut into rings (by range) and sectors (by azimuth); each bin holds the highest point
/// that falls in it. Rotating the sensor about its z axis shifts the sectors, so two scans of one
/// place compare by the best column shift, which also gives the yaw between them; each ring's
/// mean is a rotation-invariant key for a nearest-neighbour search.

#include <vector>

#include "carat/registration/point_cloud.hpp"

namespace carat {

/// Settings of the Scan Context descriptor.
struct ScanContextOptions {
  int rings = 20;              ///< radial bins over (0, max_range] (>= 1)
  int sectors = 60;            ///< azimuthal bins over 360 degrees (>= 4)
  double max_range = 80.0;     ///< metres; farther points are left out (> 0)
  double height_offset = 2.0;  ///< metres added to z (sensor frame), so the ground is > 0
  int min_occupied_bins = 30;  ///< a scan filling fewer bins has no usable descriptor (>= 1)
};

/// The descriptor of one scan.
struct ScanContext {
  int rings = 0;                ///< rows
  int sectors = 0;              ///< columns
  std::vector<float> bins;      ///< rings x sectors, row-major: max(z + offset, 0) in metres;
                                ///< 0 for an empty bin
  std::vector<float> ring_key;  ///< per ring: the mean of its bins (metres)
  int occupied_bins = 0;        ///< bins holding at least one point
  bool valid = false;           ///< occupied_bins >= the options' min_occupied_bins
};

/// The descriptor of `cloud` (points in the sensor frame, z up). Throws carat::Error for options
/// out of range.
ScanContext make_scan_context(const PointCloud& cloud, const ScanContextOptions& options = {});

/// How well two descriptors match at their best column shift.
struct ScanContextMatch {
  double distance = 1.0;  ///< 1 - mean cosine similarity of the columns both scans fill, in
                          ///< [0, 2]; 1 when no column is filled in both
  int shift = 0;          ///< sectors the candidate turns onto the query, in [0, sectors)
  double yaw = 0.0;       ///< radians in (-pi, pi]: the rotation about z of T_query_candidate
                          ///< (p_query = R_z(yaw) p_candidate) that the shift stands for
};

/// Compares `candidate` with `query` at every column shift (exhaustive, deterministic) and
/// returns the best. Throws carat::Error when their sizes differ.
ScanContextMatch match_scan_contexts(const ScanContext& query, const ScanContext& candidate);

}  // namespace carat
