// The synthetic LiDAR world: determinism (also across thread counts), point counts and ranges,
// geometric consistency with the scene, the ground-truth circuit, the drift model, KITTI-style
// output, option validation, one GICP alignment of consecutive scans and the whole synthetic
// pipeline in one call.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>

#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/registration/align.hpp"
#include "carat/registration/covariance.hpp"
#include "carat/registration/io/kitti_io.hpp"
#include "carat/registration/kdtree.hpp"
#include "carat/registration/voxel_grid.hpp"
#include "carat/sim/drift.hpp"
#include "carat/sim/kitti_writer.hpp"
#include "carat/sim/pipeline.hpp"
#include "carat/sim/sequence.hpp"
#include "carat/sim/world.hpp"

namespace carat {
namespace {

using ::testing::HasSubstr;

/// The default world, built once (construction is cheap, but scans are reused).
const SyntheticWorld& default_world() {
  static const SyntheticWorld world;
  return world;
}

bool same_points(const PointCloud& a, const PointCloud& b) {
  return a.size() == b.size() &&
         std::memcmp(a.points.data(), b.points.data(), a.size() * sizeof(Eigen::Vector3f)) == 0;
}

PointCloud to_world(const PointCloud& cloud, const Eigen::Isometry3d& T) {
  PointCloud out;
  out.points.reserve(cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    out.points.push_back((T * cloud.point(i)).cast<float>());
  }
  return out;
}

TEST(SyntheticWorldTest, ScansAreDeterministicAndSeeded) {
  const SyntheticWorld& world = default_world();
  const auto poses = world.trajectory({});
  const PointCloud a = world.scan(poses[3], 7);
  const PointCloud b = world.scan(poses[3], 7);
  EXPECT_TRUE(same_points(a, b));
  EXPECT_FALSE(same_points(a, world.scan(poses[3], 8)));  // other noise

  SyntheticWorldOptions other;
  other.seed = 2;
  const SyntheticWorld world2(other);
  EXPECT_FALSE(same_points(a, world2.scan(poses[3], 7)));  // other scene
}

TEST(SyntheticWorldTest, SequenceDoesNotDependOnThreadCount) {
  const SyntheticWorld& world = default_world();
  SyntheticTrajectoryOptions options;
  options.frames = 6;
  options.laps = 1;
  SyntheticSequence one, two;
  tbb::task_arena(1).execute([&] { one = make_synthetic_sequence(world, options); });
  tbb::task_arena(2).execute([&] { two = make_synthetic_sequence(world, options); });
  ASSERT_EQ(one.scans.size(), 6u);
  ASSERT_EQ(two.scans.size(), 6u);
  for (std::size_t k = 0; k < one.scans.size(); ++k) {
    EXPECT_TRUE(same_points(one.scans[k], two.scans[k])) << "frame " << k;
    EXPECT_TRUE(one.T_world_frame[k].isApprox(two.T_world_frame[k], 0.0));
  }
  EXPECT_FALSE(same_points(one.scans[0], one.scans[1]));
}

TEST(SyntheticWorldTest, PointsAreFiniteInRangeAndInTheExpectedBand) {
  const SyntheticWorld& world = default_world();
  const auto poses = world.trajectory({});
  const auto& o = world.options();
  // Every fifth frame of both laps (corners included), timed.
  double seconds = 0.0;
  int scans = 0;
  for (std::size_t k = 0; k < poses.size(); k += 5) {
    const Stopwatch stopwatch;
    const PointCloud cloud = world.scan(poses[k], synthetic_frame_noise_seed(o.seed, k));
    seconds += stopwatch.elapsed_s();
    ++scans;
    EXPECT_GE(cloud.size(), 15000u) << "frame " << k;
    EXPECT_LE(cloud.size(), 40000u) << "frame " << k;
    for (const Eigen::Vector3f& p : cloud.points) {
      ASSERT_TRUE(p.allFinite()) << "frame " << k;
      const double r = p.cast<double>().norm();
      ASSERT_GE(r, o.min_range - 1e-5) << "frame " << k;
      ASSERT_LE(r, o.max_range + 1e-5) << "frame " << k;
    }
  }
  std::printf("[ INFO     ] %.2f ms per %dx%d scan (mean over %d scans)\n", 1e3 * seconds / scans,
              o.beams, o.azimuth_steps, scans);
}

TEST(SyntheticWorldTest, NoiseFreePointsLieOnTheScene) {
  SyntheticWorldOptions options;
  options.range_noise = 0.0;
  const SyntheticWorld world(options);
  const auto poses = world.trajectory({});
  const Eigen::Isometry3d& T = poses[10];
  const PointCloud cloud = world.scan(T, 1);
  ASSERT_GT(cloud.size(), 1000u);
  std::size_t on_ground = 0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3d w = T * cloud.point(i);
    const double dz = w.z() - world.ground_height(w.x(), w.y());
    ASSERT_GT(dz, -1e-4) << "point " << i << " is under the ground";
    if (std::abs(dz) < 5e-5) ++on_ground;
    // Nothing lies between the sensor and the point: a ray cast towards it ends there.
    if (i % 97 == 0) {
      const Eigen::Vector3d ray = w - T.translation();
      EXPECT_NEAR(world.cast_ray(T.translation(), ray, 100.0), ray.norm(), 1e-4);
    }
  }
  // The ground (with its relief, not just the plane) holds a good share of the points.
  EXPECT_GT(on_ground, cloud.size() / 4);
  EXPECT_LT(on_ground, cloud.size() * 9 / 10);  // and the rest is scenery
}

TEST(SyntheticWorldTest, ConsecutiveScansOverlap) {
  const SyntheticWorld& world = default_world();
  SyntheticTrajectoryOptions options;
  options.frames = 100;
  const auto poses = world.trajectory(options);
  for (const std::size_t k : {std::size_t{0}, std::size_t{12}}) {
    const PointCloud scan0 = to_world(world.scan(poses[k], 1), poses[k]);
    const PointCloud scan1 = to_world(world.scan(poses[k + 1], 2), poses[k + 1]);
    const KdTree tree(scan0);
    std::size_t close = 0;
    for (const Eigen::Vector3f& p : scan1.points) {
      std::uint32_t index;
      float d2;
      ASSERT_TRUE(tree.nearest(p, &index, &d2));
      if (d2 < 0.3f * 0.3f) ++close;
    }
    EXPECT_GT(static_cast<double>(close) / static_cast<double>(scan1.size()), 0.5)
        << "frames " << k << ", " << k + 1;
  }
}

TEST(SyntheticWorldTest, TrajectoryIsAClosedCircuitWithFewMetreSpacing) {
  const SyntheticWorld& world = default_world();
  const auto poses = world.trajectory({});
  ASSERT_EQ(poses.size(), 100u);
  for (std::size_t k = 0; k < poses.size(); ++k) {
    const Eigen::Isometry3d& T = poses[k];
    EXPECT_TRUE(T.matrix().allFinite());
    EXPECT_LT((T.linear().transpose() * T.linear() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
    EXPECT_GT(T.linear().determinant(), 0.0);
    const Eigen::Vector3d t = T.translation();
    EXPECT_NEAR(t.z() - world.ground_height(t.x(), t.y()), world.options().sensor_height, 1e-9);
    if (k + 1 < poses.size() && k + 1 != 50) {
      const double step = (poses[k + 1].translation() - t).norm();
      EXPECT_GT(step, 3.0) << "frame " << k;
      EXPECT_LT(step, 6.0) << "frame " << k;
    }
    if (k < 50) {  // the same place one lap later: close, but not identical
      const Eigen::Isometry3d& L = poses[k + 50];
      const double d = (L.translation() - t).norm();
      EXPECT_LT(d, 2.0) << "frame " << k;
      EXPECT_GT(d, 0.3) << "frame " << k;
      const double angle = Eigen::AngleAxisd(T.linear().transpose() * L.linear()).angle();
      EXPECT_LT(angle, 5.0 * M_PI / 180.0);
    }
  }
  // Closing the loop: the last frame is one step before the first frame of its lap.
  EXPECT_LT((poses.back().translation() - poses[50].translation()).norm(), 6.0);
}

TEST(SyntheticWorldTest, CircuitAroundSeveralBlocksFollowsTheOuterStreets) {
  SyntheticWorldOptions options;
  options.blocks_x = 4;
  options.blocks_y = 2;
  const SyntheticWorld world(options);
  SyntheticTrajectoryOptions drive;
  drive.circuit_blocks_x = 3;
  drive.frames = 400;
  drive.laps = 1;
  drive.lap_offset = 0.0;
  const auto poses = world.trajectory(drive);
  // Centre lines: x = -W/2 or 3 (B + W) - W/2, y = -W/2 or B + W/2; corners rounded (r = 10).
  const double B = options.block_size, W = options.street_width, r = drive.corner_radius;
  const double x0 = -0.5 * W, x1 = 3.0 * (B + W) - 0.5 * W, y0 = -0.5 * W, y1 = B + 0.5 * W;
  double length = 0.0;
  for (std::size_t k = 0; k < poses.size(); ++k) {
    const Eigen::Vector3d t = poses[k].translation();
    // Distance to the rounded rectangle: to the nearest straight, or to its corner arc.
    const double cx = std::clamp(t.x(), x0 + r, x1 - r), cy = std::clamp(t.y(), y0 + r, y1 - r);
    const double to_arc = std::abs(std::hypot(t.x() - cx, t.y() - cy) - r);
    const double to_side = std::min(
        {std::abs(t.x() - x0), std::abs(t.x() - x1), std::abs(t.y() - y0), std::abs(t.y() - y1)});
    const bool in_corner = std::abs(t.x() - cx) > 0.0 && std::abs(t.y() - cy) > 0.0;
    EXPECT_LT(in_corner ? to_arc : to_side, 1e-9) << "frame " << k;
    length += (poses[(k + 1) % poses.size()].translation() - t).head<2>().norm();
  }
  // Chords of a rounded rectangle of 2 (x1 - x0) + 2 (y1 - y0) - (8 - 2 pi) r.
  const double perimeter = 2.0 * (x1 - x0) + 2.0 * (y1 - y0) - (8.0 - 2.0 * M_PI) * r;
  EXPECT_NEAR(length, perimeter, 0.01 * perimeter);
  SyntheticTrajectoryOptions too_wide = drive;
  too_wide.circuit_blocks_x = 5;
  EXPECT_THAT([&] { world.trajectory(too_wide); },
              ::testing::ThrowsMessage<Error>(
                  HasSubstr("circuit_blocks_x: must be in [1, blocks_x = 4], got 5")));
  SyntheticTrajectoryOptions none = drive;
  none.circuit_blocks_y = 0;
  EXPECT_THAT([&] { world.trajectory(none); },
              ::testing::ThrowsMessage<Error>(HasSubstr("circuit_blocks_y")));
}

TEST(SyntheticWorldTest, DriftIsExactWithoutNoiseAndGrowsWithDistance) {
  const SyntheticWorld& world = default_world();
  const auto truth = world.trajectory({});
  DriftOptions none;
  none.translation_sigma = 0.0;
  none.rotation_sigma_deg = 0.0;
  const auto same = apply_drift(truth, none);
  ASSERT_EQ(same.size(), truth.size());
  for (std::size_t k = 0; k < truth.size(); ++k) EXPECT_TRUE(same[k].isApprox(truth[k], 0.0));

  DriftOptions drift;
  drift.seed = 3;
  const auto a = apply_drift(truth, drift);
  const auto b = apply_drift(truth, drift);
  drift.seed = 4;
  const auto c = apply_drift(truth, drift);
  EXPECT_TRUE(a[0].isApprox(truth[0], 0.0));
  auto error = [&](const std::vector<Eigen::Isometry3d>& guess, std::size_t k) {
    return (guess[k].translation() - truth[k].translation()).norm();
  };
  for (std::size_t k = 0; k < truth.size(); ++k) EXPECT_TRUE(a[k].isApprox(b[k], 0.0));
  EXPECT_NE(error(a, 99), error(c, 99));
  // Error grows with the distance travelled (mean over the first and the last ten frames).
  for (const auto* guess : {&a, &c}) {
    double early = 0.0, late = 0.0;
    for (std::size_t k = 1; k <= 10; ++k) early += error(*guess, k);
    for (std::size_t k = 90; k < 100; ++k) late += error(*guess, k);
    EXPECT_GT(late, 3.0 * early);
    EXPECT_GT(late / 10.0, 0.5);  // 400 m of 1 %/0.1 deg per metre drift is metres off
  }
  DriftOptions bad;
  bad.rotation_sigma_deg = -1.0;
  EXPECT_THAT([&] { apply_drift(truth, bad); },
              ::testing::ThrowsMessage<Error>(HasSubstr("rotation_sigma_deg")));
}

TEST(SyntheticWorldTest, WritesAKittiStyleSequence) {
  const SyntheticWorld& world = default_world();
  SyntheticTrajectoryOptions options;
  options.frames = 3;
  options.laps = 1;
  const SyntheticSequence sequence = make_synthetic_sequence(world, options);
  const auto dir = std::filesystem::temp_directory_path() /
                   ("carat_world_test_" + std::to_string(::getpid())) / "seq";
  std::filesystem::remove_all(dir.parent_path());
  write_synthetic_sequence(dir, sequence);
  for (std::size_t k = 0; k < 3; ++k) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06zu.bin", k);
    EXPECT_EQ(std::filesystem::file_size(dir / name), 16 * sequence.scans[k].size()) << name;
    const PointCloud back = read_kitti_bin(dir / name, KittiFormat::kXyzi);
    EXPECT_TRUE(same_points(back, sequence.scans[k])) << name;
  }
  std::ifstream in(dir / "poses.txt");
  std::string line;
  std::size_t lines = 0;
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    std::vector<double> numbers;
    double v;
    while (fields >> v) numbers.push_back(v);
    ASSERT_EQ(numbers.size(), 12u) << line;
    const Eigen::Matrix4d M = sequence.T_world_frame[lines].matrix();
    for (int i = 0; i < 12; ++i) EXPECT_NEAR(numbers[i], M(i / 4, i % 4), 1e-6);
    ++lines;
  }
  EXPECT_EQ(lines, 3u);

  // kXyz (12 bytes per point) reads back the same points too.
  write_kitti_bin(dir / "xyz.bin", sequence.scans[0], KittiFormat::kXyz);
  EXPECT_EQ(std::filesystem::file_size(dir / "xyz.bin"), 12 * sequence.scans[0].size());
  EXPECT_TRUE(same_points(read_kitti_bin(dir / "xyz.bin", KittiFormat::kXyz), sequence.scans[0]));

  SyntheticSequence mismatched = sequence;
  mismatched.T_world_frame.pop_back();
  EXPECT_THROW(write_synthetic_sequence(dir, mismatched), Error);
  std::filesystem::remove_all(dir.parent_path());
}

TEST(SyntheticWorldTest, RejectsBadOptionsNamingTheField) {
  auto world_error = [](const std::function<void(SyntheticWorldOptions&)>& change,
                        const std::string& field) {
    SyntheticWorldOptions options;
    change(options);
    EXPECT_THAT([&] { SyntheticWorld{options}; }, ::testing::ThrowsMessage<Error>(HasSubstr(field)))
        << field;
  };
  world_error([](auto& o) { o.beams = 0; }, "beams");
  world_error([](auto& o) { o.azimuth_steps = 7; }, "azimuth_steps");
  world_error([](auto& o) { o.min_range = 0.0; }, "min_range");
  world_error([](auto& o) { o.max_range = 0.5; }, "max_range");
  world_error([](auto& o) { o.range_noise = NAN; }, "range_noise");
  world_error([](auto& o) { o.block_size = INFINITY; }, "block_size");
  world_error([](auto& o) { o.street_width = 2.0; }, "street_width");
  world_error([](auto& o) { o.ground_slope = NAN; }, "ground_slope");
  world_error([](auto& o) { o.max_elevation_deg = -30.0; }, "max_elevation_deg");
  world_error([](auto& o) { o.blocks_x = 0; }, "blocks_x");

  const SyntheticWorld& world = default_world();
  SyntheticTrajectoryOptions frames;
  frames.frames = 1;
  EXPECT_THAT([&] { world.trajectory(frames); },
              ::testing::ThrowsMessage<Error>(HasSubstr("frames")));
  SyntheticTrajectoryOptions laps;
  laps.laps = 0;
  EXPECT_THAT([&] { world.trajectory(laps); }, ::testing::ThrowsMessage<Error>(HasSubstr("laps")));
  SyntheticTrajectoryOptions radius;
  radius.corner_radius = NAN;
  EXPECT_THAT([&] { world.trajectory(radius); },
              ::testing::ThrowsMessage<Error>(HasSubstr("corner_radius")));
}

TEST(SyntheticWorldTest, GicpRecoversConsecutiveAndLoopClosurePoses) {
  const SyntheticWorld& world = default_world();
  const auto poses = world.trajectory({});
  // Consecutive frames on a straight and on a corner, and a loop closure (one lap later).
  const std::pair<std::size_t, std::size_t> pairs[] = {{0, 1}, {60, 61}, {30, 31}, {20, 70}};
  for (const auto& [k, j] : pairs) {
    auto prepare = [&](std::size_t frame) {
      PointCloud cloud =
          voxel_downsample(world.scan(poses[frame], synthetic_frame_noise_seed(1, frame)), 0.5);
      const KdTree tree(cloud);
      estimate_covariances(cloud, tree);
      return cloud;
    };
    const PointCloud target = prepare(k), source = prepare(j);
    const KdTree target_tree(target);
    // Coarse to fine: frames are about 4 m apart and the search starts at the identity.
    AlignSettings settings;
    Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();
    for (const double distance : {6.0, 3.0, 1.0}) {
      settings.max_correspondence_distance = distance;
      T_target_source =
          align(target, target_tree, source, T_target_source, settings).T_target_source;
    }
    const Eigen::Isometry3d truth = poses[k].inverse() * poses[j];
    if (k == 30) {  // a corner
      EXPECT_GT(Eigen::AngleAxisd(truth.linear()).angle(), 10.0 * M_PI / 180.0);
    }
    const Eigen::Isometry3d error = truth.inverse() * T_target_source;
    EXPECT_LT(error.translation().norm(), 0.05) << "frames " << k << ", " << j;
    EXPECT_LT(Eigen::AngleAxisd(error.linear()).angle(), 0.5 * M_PI / 180.0)
        << "frames " << k << ", " << j;
  }
}

/// A quick pipeline: a sparse sensor and a short drive.
SyntheticPipelineOptions quick_pipeline(int threads) {
  SyntheticPipelineOptions options;
  options.world.seed = 5;
  options.world.beams = 16;
  options.world.azimuth_steps = 256;
  options.drive.frames = 8;
  options.drift.seed = 5;
  options.threads = threads;
  // A sparse scene (16 beams): its last odometry pair finds 28-30 correspondences within 2 m,
  // depending on the compiler's rounding; the default floor of 29 would make that a coin toss.
  options.odometry_settings.min_correspondences = 12;
  return options;
}

TEST(SyntheticPipelineTest, ComposesTheStagesAndDoesNotDependOnThreadCount) {
  const SyntheticPipeline one = simulate_pipeline(quick_pipeline(1));
  std::size_t reported = 0;
  const SyntheticPipeline two = simulate_pipeline(
      quick_pipeline(2), [&](SyntheticPipelineStage, std::size_t, std::size_t) { ++reported; });
  EXPECT_GT(reported, 0u);
  ASSERT_EQ(one.frames.size(), 8u);
  ASSERT_EQ(one.T_world_truth.size(), 8u);
  ASSERT_EQ(one.T_world_initial.size(), 8u);

  // The stages, one by one.
  const SyntheticPipelineOptions options = quick_pipeline(1);
  const SyntheticWorld world(options.world);
  const std::vector<Eigen::Isometry3d> truth = world.trajectory(options.drive);
  const std::vector<Eigen::Isometry3d> drift = apply_drift(truth, options.drift);
  std::size_t raw = 0;
  for (std::size_t k = 0; k < truth.size(); ++k) {
    EXPECT_TRUE(truth[k].isApprox(one.T_world_truth[k], 0.0));
    EXPECT_TRUE(drift[k].isApprox(one.T_world_drift[k], 0.0));
    const PointCloud scan = world.scan(truth[k], synthetic_frame_noise_seed(options.world.seed, k));
    raw += scan.size();
    const auto frame = preprocess_frame(scan, options.preprocess, "frame");
    EXPECT_TRUE(same_points(frame->cloud(), one.frames[k]->cloud())) << k;
    EXPECT_TRUE(same_points(one.frames[k]->cloud(), two.frames[k]->cloud())) << k;
    EXPECT_TRUE(one.T_world_initial[k].isApprox(two.T_world_initial[k], 1e-12)) << k;
  }
  EXPECT_EQ(one.raw_points, raw);
  EXPECT_FALSE(one.pairs.empty());
  ASSERT_EQ(one.pairs.size(), two.pairs.size());
  for (std::size_t i = 0; i < one.pairs.size(); ++i) {
    EXPECT_EQ(one.pairs[i].source, two.pairs[i].source);
    EXPECT_EQ(one.pairs[i].target, two.pairs[i].target);
  }
}

TEST(SyntheticPipelineTest, SkipsOdometryAndGraphWhenAskedAndRejectsNoThreads) {
  SyntheticPipelineOptions options = quick_pipeline(1);
  options.odometry = false;
  options.dense_graph = false;
  const SyntheticPipeline pipeline = simulate_pipeline(options);
  ASSERT_EQ(pipeline.T_world_initial.size(), pipeline.T_world_drift.size());
  for (std::size_t k = 0; k < pipeline.T_world_drift.size(); ++k)
    EXPECT_TRUE(pipeline.T_world_initial[k].isApprox(pipeline.T_world_drift[k], 0.0));
  EXPECT_TRUE(pipeline.pairs.empty());
  options.threads = 0;
  EXPECT_THAT([&] { simulate_pipeline(options); },
              ::testing::ThrowsMessage<Error>(HasSubstr("SyntheticPipelineOptions.threads")));
}

}  // namespace
}  // namespace carat
