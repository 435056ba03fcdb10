// Scan folders: natural order, hidden and non-regular entries, poses by vertex id.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <fstream>
#include <random>

#include "carat/base/error.hpp"
#include "carat/registration/io/kitti_io.hpp"
#include "carat/registration/io/scan_folder.hpp"
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

TEST(ScanFolderTest, EntriesThatLookLikeFramesAreRefusedNotSkipped) {
  const std::string hide =
      "; move it out of the folder or hide it (a name starting with '.') to run without it";
  for (const char* odd : {"3.BIN", "3.Pcd", "3.bin~", "3.bin ", "3.bin.gz", "3.PLY.bak"}) {
    const fs::path dir = test::scratch_dir("scan_folder_odd");
    for (int k : {0, 1, 2}) {
      write_kitti_bin(dir / (std::to_string(k) + ".bin"), small_cloud(k), KittiFormat::kXyzi);
    }
    std::ofstream(dir / odd) << "x";
    EXPECT_EQ(error_of([&] { list_scan_folder(dir); }),
              (dir / odd).string() +
                  ": is named like a frame, but frames are read only from *.bin, *.pcd and *.ply "
                  "(lower case)" +
                  hide)
        << odd;
  }
  const fs::path dir = test::scratch_dir("scan_folder_dir_named_bin");
  for (int k : {0, 1}) {
    write_kitti_bin(dir / (std::to_string(k) + ".bin"), small_cloud(k), KittiFormat::kXyzi);
  }
  std::ofstream(dir / "poses.txt") << "not a scan\n";
  std::ofstream(dir / "notes.binary") << "not a scan either\n";
  fs::create_directory(dir / "extra");  // an unrelated folder beside flat frames: skipped
  EXPECT_EQ(list_scan_folder(dir).size(), 2u);
  fs::create_directory(dir / "1.5.bin");
  EXPECT_EQ(error_of([&] { list_scan_folder(dir); }),
            (dir / "1.5.bin").string() + ": is a directory named like a frame file" + hide);
  // gtsam_points dumps: every <frame>/ folder needs its points.bin.
  const fs::path nested = test::scratch_dir("scan_folder_nested_missing");
  for (const char* name : {"000000", "000001", "000002"}) {
    fs::create_directory(nested / name);
    if (std::string(name) != "000001") {
      write_kitti_bin(nested / name / "points.bin", small_cloud(1), KittiFormat::kXyz);
    }
  }
  std::ofstream(nested / "000001" / "points_compact.bin") << "x";
  std::ofstream(nested / "graph.txt") << "v0 0 0 0 0 0 0 1\n";
  EXPECT_EQ(error_of([&] { list_scan_folder(nested); }),
            (nested / "000001").string() +
                ": a folder without points.bin among <frame>/points.bin frames" + hide);
  EXPECT_TRUE(looks_like_frame_name("x.Ply"));
  EXPECT_FALSE(looks_like_frame_name("graph.txt"));
  EXPECT_FALSE(is_frame_file_name("x.BIN"));
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

TEST(ScanFolderTest, OneGraphIdRuleForWritersAndReaders) {
  // Nanosecond stamps as names: each frame's own id, exact (doubles would merge these two).
  const std::vector<ScanFile> stamped{
      {"a", "1569415453000000002"}, {"b", "1569415453000000001"}, {"c", "1569415453100000000"}};
  const std::vector<std::uint64_t> ids = scan_graph_ids(stamped);
  EXPECT_EQ(ids, (std::vector<std::uint64_t>{1569415453000000002u, 1569415453000000001u,
                                             1569415453100000000u}));
  // What a writer writes with those ids, a reader pairs back with the same frames.
  Trajectory written;
  for (std::size_t k = 0; k < stamped.size(); ++k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation().x() = static_cast<double>(k);
    written.poses.push_back(T);
    written.stamps.push_back(static_cast<double>(k));
  }
  written.ids = ids;
  const Trajectory read = parse_trajectory(format_trajectory(written, TrajectoryFormat::kGraph),
                                           TrajectoryFormat::kGraph, "odometry.txt");
  const Trajectory paired =
      poses_in_scan_order(read, TrajectoryFormat::kGraph, stamped, "odometry.txt");
  for (std::size_t k = 0; k < stamped.size(); ++k) {
    EXPECT_EQ(paired.poses[k].translation().x(), static_cast<double>(k)) << k;
    EXPECT_EQ(paired.ids[k], ids[k]);
  }
  // Names that are not all distinct numbers take their indices: "7" and "007" are one number.
  EXPECT_EQ(scan_graph_ids({{"a", "7"}, {"b", "007"}}), (std::vector<std::uint64_t>{0, 1}));
  EXPECT_EQ(scan_graph_ids({{"a", "scan"}, {"b", "2"}}), (std::vector<std::uint64_t>{0, 1}));
  EXPECT_EQ(scan_graph_ids({{"a", "99999999999999999999"}}), (std::vector<std::uint64_t>{0}));
  EXPECT_EQ(scan_graph_ids({{"a", "000010"}, {"b", "000002"}}),
            (std::vector<std::uint64_t>{10, 2}));
}

}  // namespace
}  // namespace carat
