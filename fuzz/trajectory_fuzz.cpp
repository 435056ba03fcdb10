// Fuzzes the trajectory parser in all three formats (KITTI, TUM, graph.txt): any input must either
// parse or throw carat::Error, never crash, hang or leak. Accepted input must be well formed
// (finite poses with orthonormal rotations, one stamp per pose) and survive a round trip:
// format_trajectory() must not throw on it, and parsing its text again must give the same stamps
// (and graph ids) and the same poses within 1e-6 (relative for large translations).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "carat/base/error.hpp"
#include "carat/registration/io/trajectory_io.hpp"

namespace {

bool roughly_equal(double a, double b) {
  return std::abs(a - b) <= 1e-6 * std::max(1.0, std::max(std::abs(a), std::abs(b)));
}

void check_well_formed(const carat::Trajectory& t) {
  if (t.poses.empty() || t.stamps.size() != t.poses.size()) __builtin_trap();
  for (std::size_t k = 0; k < t.poses.size(); ++k) {
    const Eigen::Matrix4d& m = t.poses[k].matrix();
    if (!m.allFinite() || !std::isfinite(t.stamps[k])) __builtin_trap();
    if (m.row(3) != Eigen::RowVector4d(0, 0, 0, 1)) __builtin_trap();
    const Eigen::Matrix3d R = m.topLeftCorner<3, 3>();
    if (!((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() <= 1e-9)) __builtin_trap();
    if (!(R.determinant() > 0.0)) __builtin_trap();
  }
}

void check_same(const carat::Trajectory& a, const carat::Trajectory& b) {
  if (a.poses.size() != b.poses.size() || a.stamps != b.stamps || a.ids != b.ids) __builtin_trap();
  for (std::size_t k = 0; k < a.poses.size(); ++k) {
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) {
        if (!roughly_equal(a.poses[k].matrix()(r, c), b.poses[k].matrix()(r, c))) __builtin_trap();
      }
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  for (carat::TrajectoryFormat format :
       {carat::TrajectoryFormat::kKitti, carat::TrajectoryFormat::kTum,
        carat::TrajectoryFormat::kGraph}) {
    carat::Trajectory trajectory;
    try {
      trajectory = carat::parse_trajectory(text, format, "fuzz.txt");
    } catch (const carat::Error&) {
      continue;
    }
    check_well_formed(trajectory);
    // Accepted input must format and parse again without an exception (an escaping exception
    // is reported by libFuzzer as a crash).
    const std::string again = carat::format_trajectory(trajectory, format);
    const carat::Trajectory reparsed = carat::parse_trajectory(again, format, "round-trip.txt");
    check_well_formed(reparsed);
    check_same(trajectory, reparsed);
  }
  return 0;
}
