// Scan folders (natural order, hidden and non-regular entries, poses by vertex id), a frame's own
// geometric constraint (planes, lines, outliers), and ATE alignments that positions alone cannot
// fix (collinear or coincident positions).
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cmath>
#include <fstream>
#include <random>

#include "carat/registration/frame.hpp"
#include "carat/registration/io/kitti_io.hpp"
#include "carat/registration/io/scan_folder.hpp"
#include "carat/registration/trajectory_error.hpp"
#include "carat/solver/error.hpp"
#include "test_support.hpp"

namespace carat {
namespace {

namespace fs = std::filesystem;

using test::error_of;

PointCloud small_cloud(int seed) {
  std::mt19937 rng(static_cast<unsigned>(seed));
  std::uniform_real_distribution<float> u(-5.0f, 5.0f);
  PointCloud cloud;
  for (int i = 0; i < 40; ++i) cloud.points.emplace_back(u(rng), u(rng), u(rng));
  return cloud;
}

TEST(ScanFolderTest, NaturalOrderComparesDigitRunsAsNumbers) {
  EXPECT_TRUE(natural_less("2", "10"));
  EXPECT_FALSE(natural_less("10", "2"));
  EXPECT_TRUE(natural_less("scan2", "scan10"));
  EXPECT_TRUE(natural_less("000009", "000010"));
  EXPECT_TRUE(natural_less("a", "b"));
  EXPECT_TRUE(natural_less("7", "07"));  // equal numbers: fewer leading zeros first
  EXPECT_FALSE(natural_less("x1", "x1"));
  std::vector<std::string> names{"10", "9", "1", "100", "0", "11", "2"};
  std::sort(names.begin(), names.end(), natural_less);
  EXPECT_EQ(names, (std::vector<std::string>{"0", "1", "2", "9", "10", "11", "100"}));
}

TEST(ScanFolderTest, ListsScansInNaturalOrderSkippingHiddenNames) {
  const fs::path dir = test::scratch_dir("scan_folder_flat");
  for (int k : {0, 1, 2, 10, 11}) {
    write_kitti_bin(dir / (std::to_string(k) + ".bin"), small_cloud(k), KittiFormat::kXyzi);
  }
  write_kitti_bin(dir / "._1.bin", small_cloud(5), KittiFormat::kXyzi);  // macOS metadata
  std::ofstream(dir / "poses.txt") << "not a scan\n";
  const std::vector<ScanFile> scans = list_scan_folder(dir);
  std::vector<std::string> names;
  for (const ScanFile& scan : scans) names.push_back(scan.name);
  EXPECT_EQ(names, (std::vector<std::string>{"0", "1", "2", "10", "11"}));
  EXPECT_EQ(scans[3].bin_format, KittiFormat::kXyzi);
  EXPECT_EQ(read_scan(scans[3]).size(), 40u);
  // A scan name that is not a regular file is an error, never skipped.
  ASSERT_EQ(::mkfifo((dir / "12.bin").c_str(), 0600), 0);
  EXPECT_EQ(
      error_of([&] { list_scan_folder(dir); }),
      (dir / "12.bin").string() + ": is not a regular file (frames are read from regular files)");
}

TEST(ScanFolderTest, NestedLayoutAndItsErrors) {
  const fs::path dir = test::scratch_dir("scan_folder_nested");
  for (const char* name : {"000000", "000001"}) {
    fs::create_directory(dir / name);
    write_kitti_bin(dir / name / "points.bin", small_cloud(1), KittiFormat::kXyz);
  }
  const std::vector<ScanFile> scans = list_scan_folder(dir);
  ASSERT_EQ(scans.size(), 2u);
  EXPECT_EQ(scans[1].name, "000001");
  EXPECT_EQ(scans[1].bin_format, KittiFormat::kXyz);
  EXPECT_EQ(list_scan_folder(dir, BinLayout::kXyzi)[0].bin_format, KittiFormat::kXyzi);
  write_kitti_bin(dir / "000002.bin", small_cloud(2), KittiFormat::kXyzi);
  EXPECT_EQ(
      error_of([&] { list_scan_folder(dir); }),
      dir.string() + ": holds both scan files and <frame>/points.bin folders; keep one layout");
  const fs::path empty = test::scratch_dir("scan_folder_empty");
  EXPECT_EQ(error_of([&] { list_scan_folder(empty); }),
            empty.string() + ": no frames (expected *.bin, *.pcd, *.ply or <frame>/points.bin)");
  EXPECT_EQ(error_of([&] { list_scan_folder(empty / "missing"); }),
            (empty / "missing").string() + ": not a folder of frames");
  EXPECT_EQ(parse_bin_layout("xyz"), BinLayout::kXyz);
  EXPECT_EQ(error_of([] { parse_bin_layout("xyzw"); }),
            "unknown .bin layout 'xyzw' (valid: auto, xyz, xyzi)");
}

TEST(ScanFolderTest, BinLayoutNamesRoundTrip) {
  for (BinLayout layout : {BinLayout::kAuto, BinLayout::kXyz, BinLayout::kXyzi}) {
    EXPECT_EQ(parse_bin_layout(to_string(layout)), layout) << to_string(layout);
  }
  EXPECT_STREQ(to_string(BinLayout::kAuto), "auto");
  EXPECT_EQ(error_of([] { parse_bin_layout("XYZ"); }),
            "unknown .bin layout 'XYZ' (valid: auto, xyz, xyzi)");
}

TEST(ScanFolderTest, GraphPosesPairWithScansByVertexId) {
  std::vector<ScanFile> scans;
  for (const char* name : {"000000", "000001", "000002"}) scans.push_back({name, name});
  Trajectory graph;  // ids in the file's order: v2, v0, v1
  for (int id : {2, 0, 1}) {
    graph.stamps.push_back(id);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation().x() = 10.0 * id;
    graph.poses.push_back(T);
  }
  const Trajectory ordered =
      poses_in_scan_order(graph, TrajectoryFormat::kGraph, scans, "graph.txt");
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(ordered.stamps[static_cast<std::size_t>(k)], k);
    EXPECT_EQ(ordered.poses[static_cast<std::size_t>(k)].translation().x(), 10.0 * k);
  }
  // KITTI / TUM: by line.
  const Trajectory by_line = poses_in_scan_order(graph, TrajectoryFormat::kKitti, scans, "p.txt");
  EXPECT_EQ(by_line.poses[0].translation().x(), 20.0);
  // A missing id names the scan; a count mismatch names both counts.
  graph.stamps[0] = 7;
  EXPECT_EQ(error_of([&] { poses_in_scan_order(graph, TrajectoryFormat::kGraph, scans, "g.txt"); }),
            "g.txt: has no vertex v2 for frame 000002 (graph poses pair with frames by id)");
  scans.pop_back();
  EXPECT_EQ(error_of([&] { poses_in_scan_order(graph, TrajectoryFormat::kGraph, scans, "g.txt"); }),
            "g.txt has 3 poses but there are 2 frames");
  // Names that are not numbers: the ids in increasing order.
  std::vector<ScanFile> named{{"a", "left"}, {"b", "right"}, {"c", "top"}};
  graph.stamps = {9, 3, 5};
  const Trajectory sorted = poses_in_scan_order(graph, TrajectoryFormat::kGraph, named, "g.txt");
  EXPECT_EQ(sorted.stamps, (std::vector<double>{3, 5, 9}));
}

/// A frame from `points` (covariances from 10 neighbours).
std::shared_ptr<Frame> frame_of(const std::vector<Eigen::Vector3f>& points) {
  PointCloud cloud;
  cloud.points = points;
  return std::make_shared<Frame>(std::move(cloud), CovarianceOptions{});
}

TEST(FrameConstraintTest, PlanesAreDegenerateScenesAreNotAndOutliersDoNotMatter) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> u(-10.0f, 10.0f);
  std::normal_distribution<float> noise(0.0f, 0.01f);
  std::vector<Eigen::Vector3f> plane, scene;
  for (int i = 0; i < 6000; ++i) plane.emplace_back(u(rng), u(rng), noise(rng));
  for (int i = 0; i < 6000; ++i) {
    const int kind = i % 3;
    if (kind == 0) scene.emplace_back(u(rng), u(rng), -1.5f + noise(rng));         // floor
    if (kind == 1) scene.emplace_back(8.0f + noise(rng), u(rng), 0.2f * u(rng));   // wall x = 8
    if (kind == 2) scene.emplace_back(u(rng), -7.0f + noise(rng), 0.2f * u(rng));  // wall y = -7
  }
  EXPECT_EQ(frame_of(plane)->constrained_dof(), 3);
  EXPECT_LT(frame_of(plane)->min_eigenvalue_ratio(), 5e-3);
  EXPECT_EQ(frame_of(scene)->constrained_dof(), 6);
  // Two walls and a floor fix everything; a few points 10 km away change nothing.
  std::vector<Eigen::Vector3f> with_outliers = scene;
  for (int k = 0; k < 5; ++k)
    with_outliers.emplace_back(10000.0f, 100.0f * static_cast<float>(k), 0.0f);
  EXPECT_EQ(frame_of(with_outliers)->constrained_dof(), 6);
  // A corridor (two parallel walls and a floor) is free along its axis.
  std::vector<Eigen::Vector3f> corridor;
  for (int i = 0; i < 6000; ++i) {
    const int kind = i % 3;
    if (kind == 0) corridor.emplace_back(u(rng), 0.1f * u(rng), -1.5f + noise(rng));
    if (kind == 1) corridor.emplace_back(u(rng), 1.0f + noise(rng), 0.1f * u(rng));
    if (kind == 2) corridor.emplace_back(u(rng), -1.0f + noise(rng), 0.1f * u(rng));
  }
  EXPECT_EQ(frame_of(corridor)->constrained_dof(), 5);
}

Eigen::Isometry3d pose(double yaw, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = t;
  return T;
}

TEST(AteAlignmentTest, CollinearPositionsTakeTheRotationAboutTheirLineFromOrientations) {
  // The estimate drives a straight line with identity orientation; the reference is the same
  // drive rolled by 30 degrees about that line and shifted. Positions cannot see the roll.
  const Eigen::Isometry3d T_ref_est = [] {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(0.5236, Eigen::Vector3d::UnitX()).toRotationMatrix();
    T.translation() = Eigen::Vector3d(1, 2, 3);
    return T;
  }();
  std::vector<Eigen::Isometry3d> estimate, reference;
  for (int k = 0; k < 10; ++k) {
    estimate.push_back(pose(0.0, Eigen::Vector3d(k, 0, 0)));
    reference.push_back(T_ref_est * estimate.back());
  }
  const AteStatistics ate = compute_ate(estimate, reference);
  EXPECT_LT(ate.rmse, 1e-9);
  EXPECT_LT(ate.rotation_max_deg, 1e-6);
  EXPECT_TRUE(ate.T_reference_estimate.isApprox(T_ref_est, 1e-9));
  // Coincident positions (a robot turning on the spot): the rotation comes from orientations.
  std::vector<Eigen::Isometry3d> spin_estimate, spin_reference;
  for (int k = 0; k < 6; ++k) {
    spin_estimate.push_back(pose(0.3 * k, Eigen::Vector3d(5, 5, 0)));
    spin_reference.push_back(T_ref_est * spin_estimate.back());
  }
  const AteStatistics spin = compute_ate(spin_estimate, spin_reference);
  EXPECT_LT(spin.rmse, 1e-9);
  EXPECT_LT(spin.rotation_max_deg, 1e-6);
}

}  // namespace
}  // namespace carat
