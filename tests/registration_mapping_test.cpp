// The mapping pipeline (carat/registration/mapping.hpp) is its stages run in order, PGO reuses
// given registrations exactly, and opening scans (scan_opening.hpp) checks what a map needs.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <random>

#include "carat/base/error.hpp"
#include "carat/base/stage_times.hpp"
#include "carat/registration/io/kitti_io.hpp"
#include "carat/registration/mapping.hpp"
#include "carat/registration/odometry.hpp"
#include "carat/registration/scan_opening.hpp"
#include "registration_test_drive.hpp"
#include "test_support.hpp"

namespace carat {
namespace {

using ::testing::HasSubstr;

/// A 12-frame drive with drift.
const test::DriftingDrive& drive() {
  static const test::DriftingDrive d = test::drifting_drive(
      3, 12, 1, {.seed = 4, .translation_sigma = 0.005, .rotation_sigma_deg = 0.03});
  return d;
}

bool same_poses(const std::vector<Eigen::Isometry3d>& a, const std::vector<Eigen::Isometry3d>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t k = 0; k < a.size(); ++k)
    if (std::memcmp(a[k].matrix().data(), b[k].matrix().data(), 16 * sizeof(double)) != 0)
      return false;
  return true;
}

TEST(MappingTest, MapFramesRunsTheStagesInOrder) {
  FrameStore store(drive().frames);
  MappingOptions options;
  options.num_threads = 2;
  options.close_loops = true;
  const MappingResult mapped = map_frames(store, drive().initial, options);
  // The stages called one by one give the same poses, bit for bit.
  const LoopClosureResult loops = close_loops(store, drive().initial, [] {
    LoopClosureOptions o;
    o.num_threads = 2;
    return o;
  }());
  DenseGraphOptions graph;
  graph.num_threads = 2;
  const std::vector<FramePair> pairs = build_dense_graph(store, loops.T_world_frame, graph);
  GlobalRegistrationOptions gre = MappingOptions::default_registration();
  gre.num_threads = 2;
  const GlobalRegistrationResult direct =
      optimize_registration(store, pairs, loops.T_world_frame, gre);
  ASSERT_TRUE(mapped.graph.loops.has_value());
  EXPECT_EQ(mapped.graph.loops->candidates.size(), loops.candidates.size());
  EXPECT_EQ(mapped.graph.pairs.size(), pairs.size());
  EXPECT_TRUE(same_poses(mapped.T_world_frame, direct.T_world_frame));
  EXPECT_EQ(mapped.summary.num_iterations, direct.summary.num_iterations);
  EXPECT_EQ(mapped.factor_costs, direct.factor_costs);
  EXPECT_EQ(options.registration.solver.max_iterations, 100);
  for (const char* stage : {"loops", "dense_graph", "factors", "solve"})
    EXPECT_TRUE(mapped.times.ran(stage)) << stage;
  EXPECT_FALSE(mapped.times.ran("pair_registration"));
  // The optimization stage alone on the graph gives the same again.
  const MappingResult again = optimize_map(store, mapped.graph, options);
  EXPECT_TRUE(same_poses(again.T_world_frame, mapped.T_world_frame));
}

TEST(MappingTest, PoseGraphReusesRegistrationsExactly) {
  FrameStore store(drive().frames);
  MappingOptions options;
  options.num_threads = 2;
  options.method = MappingMethod::kPoseGraph;
  const MapGraph graph = build_map_graph(store, drive().initial, options);
  const MappingResult first = optimize_map(store, graph, options);
  ASSERT_EQ(first.registrations.size(), graph.pairs.size());
  EXPECT_TRUE(first.times.ran("pair_registration"));
  const MappingResult reused = optimize_map(store, graph, options, {}, first.registrations);
  EXPECT_TRUE(same_poses(reused.T_world_frame, first.T_world_frame));
  EXPECT_FALSE(reused.times.ran("pair_registration"));
  const std::vector<PairRegistration> short_list(first.registrations.begin(),
                                                 first.registrations.begin() + 3);
  EXPECT_THAT(
      test::error_of([&] { optimize_map(store, graph, options, {}, short_list); }),
      HasSubstr("mapping: 3 registrations for " + std::to_string(graph.pairs.size()) + " pairs"));
  std::vector<PairRegistration> swapped = first.registrations;
  std::swap(swapped[0], swapped[1]);
  EXPECT_THAT(test::error_of([&] { optimize_map(store, graph, options, {}, swapped); }),
              HasSubstr("mapping: registration 0 is of frames"));
}

TEST(MappingTest, RefusesBadSettings) {
  FrameStore store(drive().frames);
  MappingOptions options;
  options.num_threads = 0;
  EXPECT_EQ(test::error_of([&] { build_map_graph(store, drive().initial, options); }),
            "mapping: num_threads must be >= 1, got 0");
  EXPECT_EQ(test::error_of([] { parse_mapping_method("icp"); }),
            "unknown mapping method 'icp' (valid: gre, pgo)");
  EXPECT_EQ(parse_mapping_method("pgo"), MappingMethod::kPoseGraph);
  EXPECT_STREQ(to_string(MappingMethod::kRegistration), "gre");
}

// Code written for frames in memory still builds (with a deprecation warning) and gets what a
// resident store gives.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"
TEST(MappingTest, DeprecatedFrameSpanOverloadsGiveTheStoreResults) {
  const std::vector<std::shared_ptr<const Frame>>& frames = drive().frames;
  FrameStore store(frames);
  const std::vector<FramePair> pairs = build_dense_graph(store, drive().initial);
  EXPECT_EQ(build_dense_graph(frames, drive().initial).size(), pairs.size());
  const std::vector<FramePair> first(pairs.begin(), pairs.begin() + 3);
  const auto a = register_pairs(frames, first, drive().initial, AlignSettings{}, 2);
  const auto b = register_pairs(store, first, drive().initial, AlignSettings{}, 2);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k)
    EXPECT_TRUE(a[k].T_target_source.isApprox(b[k].T_target_source, 0.0));
  const OdometryResult odometry = run_odometry(frames, drive().initial, AlignSettings{}, 2);
  EXPECT_EQ(odometry.describe_unreliable_steps(frames), odometry.describe_unreliable_steps(store));
  EXPECT_EQ(test::error_of([&] {
              build_dense_graph(std::vector<std::shared_ptr<const Frame>>(2), drive().initial);
            }),
            "frame store: frame 0 is null");
}
#pragma GCC diagnostic pop

TEST(StageTimesTest, AddsPerStageInFirstRunOrder) {
  StageTimes times;
  times.add("b", 1.5);
  times.add("a", 0.25);
  times.add("b", 0.5);
  ASSERT_EQ(times.entries().size(), 2u);
  EXPECT_EQ(times.entries()[0].first, "b");
  EXPECT_EQ(times.seconds("b"), 2.0);
  EXPECT_EQ(times.seconds("c"), 0.0);
  EXPECT_FALSE(times.ran("c"));
  EXPECT_EQ(times.total_s(), 2.25);
}

/// Writes `points` as a KITTI .bin scan.
void write_scan(const std::filesystem::path& path, const std::vector<Eigen::Vector3d>& points) {
  PointCloud cloud;
  for (const auto& p : points) cloud.points.push_back(p.cast<float>());
  write_kitti_bin(path, cloud, KittiFormat::kXyzi);
}

TEST(ScanOpeningTest, ChecksPointCountsAndGeometry) {
  const std::filesystem::path dir = test::scratch_dir("scan_opening");
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-10.0, 10.0);
  std::vector<Eigen::Vector3d> box, plane, few;
  for (int k = 0; k < 3000; ++k) {  // points on the six faces of a box: all directions fixed
    Eigen::Vector3d p(u(rng), u(rng), u(rng));
    p[k % 3] = (k % 2 == 0) ? 10.0 : -10.0;
    box.push_back(p);
    plane.emplace_back(u(rng), u(rng), 0.0);
  }
  for (int k = 0; k < 10; ++k) few.push_back(box[static_cast<std::size_t>(k)]);
  write_scan(dir / "000000.bin", box);
  write_scan(dir / "000001.bin", box);
  write_scan(dir / "plane.bin", plane);
  write_scan(dir / "few.bin", few);
  const auto file = [&](const std::string& name) {
    return ScanFile{dir / name, name, KittiFormat::kXyzi};
  };
  OpenScansOptions options;
  EXPECT_EQ(test::error_of([&] {
              open_scans({file("000000.bin"), file("few.bin")}, options);
            }),
            (dir / "few.bin").string() + ": only 10 points (at least 29 are needed)");
  EXPECT_THAT(test::error_of([&] {
                open_scans({file("000000.bin"), file("plane.bin")}, options);
              }),
              HasSubstr((dir / "plane.bin").string() + ": the scan fixes only "));
  EXPECT_EQ(test::error_of([&] { open_scans({}, options); }), "open scans: no scans given");
  // Odometry's setting: a plane is opened, its steps are judged later.
  options.require_constrained = false;
  EXPECT_EQ(open_scans({file("000000.bin"), file("plane.bin")}, options)->size(), 2u);
  // Read now or on demand: the same frames.
  options.require_constrained = true;
  const auto resident = open_scans({file("000000.bin"), file("000001.bin")}, options);
  options.max_bytes = std::size_t{1} << 30;
  const auto on_demand = open_scans({file("000000.bin"), file("000001.bin")}, options);
  EXPECT_TRUE(resident->resident());
  EXPECT_FALSE(on_demand->resident());
  EXPECT_EQ(on_demand->frame_points(), std::vector<std::size_t>(2, 0));  // nothing read yet
  EXPECT_EQ(on_demand->get(1)->size(), resident->get(1)->size());
  EXPECT_EQ(on_demand->frame_points()[1], resident->frame_points()[1]);
  EXPECT_GT(resident->frame_points()[1], 100u);
}

}  // namespace
}  // namespace carat
