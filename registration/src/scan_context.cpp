#include "carat/registration/scan_context.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "carat/base/error.hpp"

namespace carat {
namespace {

void check_options(const ScanContextOptions& o) {
  if (o.rings < 1) throw Error("Scan Context: rings must be >= 1, got " + std::to_string(o.rings));
  if (o.sectors < 4) {
    throw Error("Scan Context: sectors must be >= 4, got " + std::to_string(o.sectors));
  }
  if (!(std::isfinite(o.max_range) && o.max_range > 0.0)) {
    throw Error("Scan Context: max_range must be finite and > 0 (metres), got " +
                std::to_string(o.max_range));
  }
  if (!std::isfinite(o.height_offset)) throw Error("Scan Context: height_offset is not finite");
  if (o.min_occupied_bins < 1) {
    throw Error("Scan Context: min_occupied_bins must be >= 1, got " +
                std::to_string(o.min_occupied_bins));
  }
}

}  // namespace

ScanContext make_scan_context(const PointCloud& cloud, const ScanContextOptions& options) {
  check_options(options);
  ScanContext sc;
  sc.rings = options.rings;
  sc.sectors = options.sectors;
  const auto bins = static_cast<std::size_t>(sc.rings) * static_cast<std::size_t>(sc.sectors);
  sc.bins.assign(bins, 0.0f);
  std::vector<unsigned char> filled(bins, 0);
  const double two_pi = 2.0 * std::numbers::pi;
  for (const Eigen::Vector3f& p : cloud.points) {
    const double x = p.x();
    const double y = p.y();
    const double range = std::hypot(x, y);
    if (!(range > 0.0) || range > options.max_range) continue;
    const int ring =
        std::min(options.rings - 1, static_cast<int>(range / options.max_range * options.rings));
    double azimuth = std::atan2(y, x);  // (-pi, pi]
    if (azimuth < 0.0) azimuth += two_pi;
    const int sector =
        std::min(options.sectors - 1, static_cast<int>(azimuth / two_pi * options.sectors));
    const std::size_t bin = static_cast<std::size_t>(ring) * static_cast<std::size_t>(sc.sectors) +
                            static_cast<std::size_t>(sector);
    const float height =
        std::max(0.0f, static_cast<float>(static_cast<double>(p.z()) + options.height_offset));
    sc.bins[bin] = filled[bin] ? std::max(sc.bins[bin], height) : height;
    filled[bin] = 1;
  }
  sc.ring_key.assign(static_cast<std::size_t>(sc.rings), 0.0f);
  for (int r = 0; r < sc.rings; ++r) {
    double sum = 0.0;
    for (int s = 0; s < sc.sectors; ++s) {
      const std::size_t bin = static_cast<std::size_t>(r) * static_cast<std::size_t>(sc.sectors) +
                              static_cast<std::size_t>(s);
      sum += sc.bins[bin];
      sc.occupied_bins += filled[bin];
    }
    sc.ring_key[static_cast<std::size_t>(r)] = static_cast<float>(sum / sc.sectors);
  }
  sc.valid = sc.occupied_bins >= options.min_occupied_bins;
  return sc;
}

ScanContextMatch match_scan_contexts(const ScanContext& query, const ScanContext& candidate) {
  if (query.rings != candidate.rings || query.sectors != candidate.sectors ||
      query.bins.size() != candidate.bins.size()) {
    throw Error("Scan Context: descriptors of different sizes (" + std::to_string(query.rings) +
                " x " + std::to_string(query.sectors) + " and " + std::to_string(candidate.rings) +
                " x " + std::to_string(candidate.sectors) + ")");
  }
  const int R = query.rings;
  const int S = query.sectors;
  // Columns as contiguous vectors with their norms.
  const auto columns = [&](const ScanContext& sc, std::vector<double>* cols,
                           std::vector<double>* norms) {
    cols->assign(static_cast<std::size_t>(R) * static_cast<std::size_t>(S), 0.0);
    norms->assign(static_cast<std::size_t>(S), 0.0);
    for (int s = 0; s < S; ++s) {
      double sq = 0.0;
      for (int r = 0; r < R; ++r) {
        const double v = sc.bins[static_cast<std::size_t>(r * S + s)];
        (*cols)[static_cast<std::size_t>(s * R + r)] = v;
        sq += v * v;
      }
      (*norms)[static_cast<std::size_t>(s)] = std::sqrt(sq);
    }
  };
  std::vector<double> q, c, qn, cn;
  columns(query, &q, &qn);
  columns(candidate, &c, &cn);
  ScanContextMatch best;
  for (int shift = 0; shift < S; ++shift) {
    double similarity = 0.0;
    int count = 0;
    for (int j = 0; j < S; ++j) {
      const int k = ((j - shift) % S + S) % S;  // candidate column that lands on query column j
      const double nq = qn[static_cast<std::size_t>(j)];
      const double nc = cn[static_cast<std::size_t>(k)];
      if (nq == 0.0 || nc == 0.0) continue;
      double dot = 0.0;
      const double* a = &q[static_cast<std::size_t>(j * R)];
      const double* b = &c[static_cast<std::size_t>(k * R)];
      for (int r = 0; r < R; ++r) dot += a[r] * b[r];
      similarity += dot / (nq * nc);
      ++count;
    }
    const double distance = count ? 1.0 - similarity / count : 1.0;
    if (distance < best.distance) {
      best.distance = distance;
      best.shift = shift;
    }
  }
  double yaw = 2.0 * std::numbers::pi * best.shift / S;
  if (yaw > std::numbers::pi) yaw -= 2.0 * std::numbers::pi;
  best.yaw = yaw;
  return best;
}

}  // namespace carat
