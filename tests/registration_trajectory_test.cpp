// Trajectory files (KITTI, TUM, graph.txt), Umeyama alignment, ATE statistics and stamp
// association.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numeric>
#include <random>
#include <span>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/registration/io/trajectory_io.hpp"
#include "carat/registration/trajectory_error.hpp"
#include "test_support.hpp"

namespace carat {
namespace {

Eigen::Isometry3d random_pose(std::mt19937& rng, double translation_scale = 10.0) {
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
  q.normalize();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q.toRotationMatrix();
  T.translation() = translation_scale * Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
  return T;
}

Trajectory random_trajectory(std::mt19937& rng, TrajectoryFormat format, int n) {
  Trajectory trajectory;
  std::uniform_real_distribution<double> gap(0.01, 0.2);
  double stamp = 1341847980.722988;
  for (int k = 0; k < n; ++k) {
    trajectory.poses.push_back(random_pose(rng));
    switch (format) {
      case TrajectoryFormat::kKitti:
        trajectory.stamps.push_back(k);
        break;
      case TrajectoryFormat::kTum:
        stamp += gap(rng);
        trajectory.stamps.push_back(stamp);
        break;
      case TrajectoryFormat::kGraph:
        trajectory.stamps.push_back((k * 7) % n);  // unique, not sorted (n prime)
        break;
    }
  }
  return trajectory;
}

void expect_same(const Trajectory& a, const Trajectory& b, double tolerance) {
  ASSERT_EQ(a.poses.size(), b.poses.size());
  ASSERT_EQ(a.stamps.size(), b.stamps.size());
  for (std::size_t k = 0; k < a.poses.size(); ++k) {
    EXPECT_EQ(a.stamps[k], b.stamps[k]) << "pose " << k;
    EXPECT_LE((a.poses[k].matrix() - b.poses[k].matrix()).cwiseAbs().maxCoeff(), tolerance)
        << "pose " << k;
  }
}

// The message of the carat::Error that parse_trajectory throws (fails the test if none).
std::string parse_error(const std::string& text, TrajectoryFormat format) {
  try {
    (void)parse_trajectory(text, format, "t.txt");
  } catch (const Error& error) {
    return error.what();
  }
  ADD_FAILURE() << "no error for: " << text.substr(0, 200);
  return "";
}

#define EXPECT_PARSE_ERROR(text, format, substring)                       \
  EXPECT_NE(parse_error(text, format).find(substring), std::string::npos) \
      << "expected '" << (substring) << "', got '" << parse_error(text, format) << "'"

constexpr TrajectoryFormat kKitti = TrajectoryFormat::kKitti;
constexpr TrajectoryFormat kTum = TrajectoryFormat::kTum;
constexpr TrajectoryFormat kGraph = TrajectoryFormat::kGraph;
const std::string kIdentityKitti = "1 0 0 0 0 1 0 0 0 0 1 0\n";

TEST(TrajectoryIoTest, FormatNames) {
  EXPECT_EQ(parse_trajectory_format("kitti"), kKitti);
  EXPECT_EQ(parse_trajectory_format("tum"), kTum);
  EXPECT_EQ(parse_trajectory_format("graph"), kGraph);
  for (TrajectoryFormat format : {kKitti, kTum, kGraph}) {
    EXPECT_EQ(parse_trajectory_format(to_string(format)), format) << to_string(format);
  }
  EXPECT_STREQ(to_string(kTum), "tum");
  EXPECT_EQ(test::error_of([] { parse_trajectory_format("euroc"); }),
            "unknown trajectory format 'euroc' (valid: kitti, tum, graph)");
}

TEST(TrajectoryIoTest, RoundTripsAllFormats) {
  std::mt19937 rng(7);
  const auto dir = test::scratch_dir("trajectory_round_trip");
  for (TrajectoryFormat format : {kKitti, kTum, kGraph}) {
    SCOPED_TRACE(static_cast<int>(format));
    const Trajectory original = random_trajectory(rng, format, 23);
    const auto path = dir / "trajectory.txt";
    write_trajectory(path, original, format);
    expect_same(read_trajectory(path, format), original, 1e-9);
    const Trajectory reparsed = parse_trajectory(format_trajectory(original, format), format, "x");
    expect_same(reparsed, original, 1e-9);
  }
}

TEST(TrajectoryIoTest, ReadsEachFormat) {
  const Trajectory kitti = parse_trajectory(
      "1 0 0 1.5 0 1 0 -2 0 0 1 3e2\r\n\r\n0 -1 0 4 1 0 0 5 0 0 1 6\n", kKitti, "k.txt");
  ASSERT_EQ(kitti.poses.size(), 2u);
  EXPECT_EQ(kitti.stamps, (std::vector<double>{0, 1}));
  EXPECT_TRUE(kitti.poses[0].translation().isApprox(Eigen::Vector3d(1.5, -2, 300)));
  EXPECT_NEAR(kitti.poses[1].linear()(1, 0), 1.0, 1e-15);

  const Trajectory tum = parse_trajectory(
      "# timestamp tx ty tz qx qy qz qw\n  # indented comment\n"
      "1305031102.175304 1 2 3 0 0 0 1\n1305031102.2 +4 5 6 0 0 0.7071067811865476 "
      "0.7071067811865476\n",
      kTum, "t.txt");
  ASSERT_EQ(tum.poses.size(), 2u);
  EXPECT_EQ(tum.stamps[0], 1305031102.175304);
  EXPECT_TRUE(tum.poses[1].translation().isApprox(Eigen::Vector3d(4, 5, 6)));
  EXPECT_NEAR(tum.poses[1].linear()(1, 0), 1.0, 1e-15);  // 90 degrees about z

  const Trajectory graph =
      parse_trajectory("v3 1 2 3 0 0 0 1\nv10 4 5 6 1 0 0 0\n", kGraph, "graph.txt");
  EXPECT_EQ(graph.stamps, (std::vector<double>{3, 10}));
  EXPECT_NEAR(graph.poses[1].linear()(1, 1), -1.0, 1e-15);  // 180 degrees about x
}

TEST(TrajectoryIoTest, ReorthonormalizesAndNormalizesNearlyValidRotations) {
  const Trajectory kitti =
      parse_trajectory("1.0001 0.0002 0 0 -0.0002 0.9999 0 0 0 0 1 0\n", kKitti, "k.txt");
  const Eigen::Matrix3d R = kitti.poses[0].linear();
  EXPECT_LE((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 1e-14);
  EXPECT_NEAR(R.determinant(), 1.0, 1e-14);

  const Trajectory tum = parse_trajectory("0 0 0 0 0 0 0 1.0009\n", kTum, "t.txt");
  EXPECT_LE((tum.poses[0].linear() - Eigen::Matrix3d::Identity()).norm(), 1e-14);
}

TEST(TrajectoryIoTest, KittiErrorsNameFileAndLine) {
  EXPECT_PARSE_ERROR("1 0 0 0 0 1 0 0 0 0 1\n", kKitti,
                     "t.txt:1: KITTI pose (3x4 row-major [R|t]) needs 12 fields, found 11");
  EXPECT_PARSE_ERROR(kIdentityKitti + kIdentityKitti + "1 0 0 0 0 1 0 0 0 0 1 0 7\n", kKitti,
                     "t.txt:3: KITTI pose (3x4 row-major [R|t]) needs 12 fields, found 13");
  EXPECT_PARSE_ERROR(kIdentityKitti + "1 abc 0 0 0 1 0 0 0 0 1 0\n", kKitti,
                     "t.txt:2: cannot read R01 from 'abc'");
  EXPECT_PARSE_ERROR("1 0 0 0 0 1 0 0 0 0 1 0.5x\n", kKitti, "t.txt:1: cannot read tz from '0.5x'");
  EXPECT_PARSE_ERROR("1 0 0 nan 0 1 0 0 0 0 1 0\n", kKitti, "t.txt:1: tx is not finite");
  EXPECT_PARSE_ERROR("1 0 0 0 0 1 0 inf 0 0 1 0\n", kKitti, "t.txt:1: ty is not finite");
  EXPECT_PARSE_ERROR("1 0 0 0 0 1 0 0 0 0 1 -inf\n", kKitti, "t.txt:1: tz is not finite");
  EXPECT_PARSE_ERROR("1 0 0 1e999 0 1 0 0 0 0 1 0\n", kKitti,
                     "t.txt:1: tx '1e999' is out of range");
  EXPECT_PARSE_ERROR("2 0 0 0 0 2 0 0 0 0 2 0\n", kKitti, "t.txt:1: rotation is not orthonormal");
  EXPECT_PARSE_ERROR("1 0 0 0 0 1 0 0 0.01 0 1 0\n", kKitti,
                     "t.txt:1: rotation is not orthonormal");
  EXPECT_PARSE_ERROR("1 0 0 0 0 1 0 0 0 0 -1 0\n", kKitti, "t.txt:1: rotation is a reflection");
  EXPECT_PARSE_ERROR("1e300 0 0 0 0 1e300 0 0 0 0 1e300 0\n", kKitti,
                     "t.txt:1: rotation is not orthonormal");
  // Blank lines (also CRLF ones) count for line numbers but are skipped.
  EXPECT_PARSE_ERROR("\n \r\n" + kIdentityKitti + "\t\n1 0 0\r\n", kKitti, "t.txt:5: ");
  // '#' is not a comment in KITTI files.
  EXPECT_PARSE_ERROR("# comment\n" + kIdentityKitti, kKitti, "t.txt:1: ");
}

TEST(TrajectoryIoTest, TumErrorsNameFileAndLine) {
  EXPECT_PARSE_ERROR("1 0 0 0 0 0 1\n", kTum,
                     "t.txt:1: TUM pose (stamp tx ty tz qx qy qz qw) needs 8 fields, found 7");
  EXPECT_PARSE_ERROR("1 0 0 0 0 0 0 1 # trailing\n", kTum, "needs 8 fields, found 10");
  EXPECT_PARSE_ERROR("1 0 0 0 0 0 0 1\n2 0 0 zero 0 0 0 1\n", kTum,
                     "t.txt:2: cannot read tz from 'zero'");
  EXPECT_PARSE_ERROR("1 0 0 0 0 0 0 1\n2 0 0 0 0 0 0 1\n1.5 0 0 0 0 0 0 1\n", kTum,
                     "t.txt:3: stamp 1.5 does not increase (line 2 has 2)");
  EXPECT_PARSE_ERROR("# c\n1 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n", kTum,
                     "t.txt:3: stamp 1 does not increase (line 2 has 1)");
  EXPECT_PARSE_ERROR("nan 0 0 0 0 0 0 1\n", kTum, "t.txt:1: stamp is not finite");
  EXPECT_PARSE_ERROR("1 0 0 0 0 0 0 inf\n", kTum, "t.txt:1: qw is not finite");
  EXPECT_PARSE_ERROR("1 0 0 0 0 0 0 0\n", kTum, "t.txt:1: quaternion is zero");
  EXPECT_PARSE_ERROR("1 0 0 0 0 0 0 2\n", kTum, "t.txt:1: quaternion is not normalized (norm 2");
  EXPECT_PARSE_ERROR("1 0 0 0 1e200 1e200 0 0\n", kTum, "t.txt:1: quaternion is not normalized");
}

TEST(TrajectoryIoTest, GraphErrorsNameFileAndLine) {
  EXPECT_PARSE_ERROR("v0 0 0 0 0 0 0\n", kGraph,
                     "t.txt:1: graph pose (vN tx ty tz qx qy qz qw) needs 8 fields, found 7");
  EXPECT_PARSE_ERROR("x0 0 0 0 0 0 0 1\n", kGraph,
                     "t.txt:1: expected a vertex id 'vN', found 'x0'");
  EXPECT_PARSE_ERROR("v-1 0 0 0 0 0 0 1\n", kGraph, "t.txt:1: expected a vertex id");
  EXPECT_PARSE_ERROR("v1a 0 0 0 0 0 0 1\n", kGraph, "t.txt:1: cannot read a vertex id");
  EXPECT_PARSE_ERROR("v99999999999999999999 0 0 0 0 0 0 1\n", kGraph,
                     "t.txt:1: cannot read a vertex id");
  EXPECT_PARSE_ERROR("v0 0 0 0 0 0 0 1\nv1 0 0 0 0 0 0 1\n\nv1 1 0 0 0 0 0 1\n", kGraph,
                     "t.txt:4: vertex v1 was already defined on line 2");
  EXPECT_PARSE_ERROR("v0 0 0 0 0 0 0 -0.5\n", kGraph, "t.txt:1: quaternion is not normalized");
  EXPECT_PARSE_ERROR("v0 1 2 3 0 0 0 1 junk\n", kGraph, "needs 8 fields, found 9");
  EXPECT_PARSE_ERROR("# comment\n", kGraph, "t.txt:1: ");
}

TEST(TrajectoryIoTest, GraphIdsKeepEveryDigit) {
  // Nanosecond stamps (19 digits) one apart: the same double, different ids.
  const std::string text =
      "v1569415453000000001 1 0 0 0 0 0 1\nv1569415453000000002 2 0 0 0 0 0 1\n"
      "v18446744073709551615 3 0 0 0 0 0 1\n";
  const Trajectory t = parse_trajectory(text, kGraph, "t.txt");
  EXPECT_EQ(t.ids, (std::vector<std::uint64_t>{1569415453000000001u, 1569415453000000002u,
                                               18446744073709551615u}));
  EXPECT_EQ(format_trajectory(t, kGraph), text);
  EXPECT_PARSE_ERROR("v18446744073709551616 0 0 0 0 0 0 1\n", kGraph,
                     "t.txt:1: cannot read a vertex id (v0 ... v18446744073709551615)");
  // Ids, when given, are what the writer writes; they must be unique and one per pose.
  Trajectory written;
  written.poses = {Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity()};
  written.stamps = {0.0, 1.0};
  written.ids = {7, 7};
  EXPECT_EQ(test::error_of([&] { (void)format_trajectory(written, kGraph); }),
            "cannot format trajectory: graph id v7 is repeated");
  written.ids = {7};
  EXPECT_EQ(test::error_of([&] { (void)format_trajectory(written, kGraph); }),
            "cannot format trajectory: 1 graph ids for 2 poses");
}

TEST(TrajectoryIoTest, EmptyAndPathologicalInput) {
  for (TrajectoryFormat format : {kKitti, kTum, kGraph}) {
    EXPECT_PARSE_ERROR("", format, "t.txt: no ");
    EXPECT_PARSE_ERROR("\n  \r\n\t\n", format, "poses (the file is empty");
  }
  EXPECT_PARSE_ERROR("# only comments\n", kTum, "t.txt: no TUM poses");
  // Very long lines and numbers: an error with a short message, no crash. A line over 64 KiB is
  // refused before it is split (the line bound of every text reader).
  std::string long_line;
  for (int k = 0; k < 200000; ++k) long_line += "1 ";
  EXPECT_PARSE_ERROR(long_line, kKitti, "t.txt:1: line is longer than 65536 bytes");
  std::string many_fields;
  for (int k = 0; k < 20000; ++k) many_fields += "1 ";
  EXPECT_PARSE_ERROR(many_fields, kKitti, "needs 12 fields, found 20000");
  const std::string huge(60000, '9');
  const std::string message = parse_error("0 0 0 " + huge + " 0 0 0 1\n", kTum);
  EXPECT_NE(message.find("t.txt:1: tz '99999"), std::string::npos) << message.substr(0, 200);
  EXPECT_LT(message.size(), 200u);
  // Text without a line break stops at the bound; NUL bytes (e.g. /dev/zero) at once.
  EXPECT_PARSE_ERROR(std::string(200000, '7'), kTum, "t.txt:1: line is longer than 65536");
  EXPECT_PARSE_ERROR(std::string(200000, '\0'), kTum, "t.txt:1: holds a NUL byte");
  EXPECT_PARSE_ERROR(std::string("0 0 0 0 0 0 0 1\n\0\n", 18), kTum,
                     "t.txt:2: holds a NUL byte (a binary file?)");
  std::string binary("v0 1 2 3 0 0 0 1\n\x01\xff\x00 garbage\n", 29);
  EXPECT_PARSE_ERROR(binary, kGraph, "t.txt:2: ");
}

TEST(TrajectoryIoTest, ReadAndWriteErrorsNameThePath) {
  const auto dir = test::scratch_dir("trajectory_files");
  const auto expect_read_error = [](const std::filesystem::path& path, const std::string& what) {
    try {
      (void)read_trajectory(path, kKitti);
      ADD_FAILURE() << "no error for " << path;
    } catch (const Error& error) {
      EXPECT_NE(std::string(error.what()).find(what), std::string::npos) << error.what();
    }
  };
  expect_read_error(dir / "missing.txt", "missing.txt: no such file");
  expect_read_error(dir, "is a directory");
  std::ofstream(dir / "empty.txt").close();
  expect_read_error(dir / "empty.txt", "empty.txt: no KITTI poses");
  std::ofstream(dir / "bad.txt") << kIdentityKitti << "1 0 0 0 0 1 0 0 0 0 1\n";
  expect_read_error(dir / "bad.txt", "bad.txt:2: KITTI pose");

  Trajectory t;
  t.poses = {Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity()};
  t.stamps = {1.0, 1.0};
  const auto expect_write_error = [&](TrajectoryFormat format, const std::string& what) {
    try {
      write_trajectory(dir / "out.txt", t, format);
      ADD_FAILURE() << "no error";
    } catch (const Error& error) {
      EXPECT_NE(std::string(error.what()).find(what), std::string::npos) << error.what();
    }
    EXPECT_FALSE(std::filesystem::exists(dir / "out.txt"));
  };
  expect_write_error(kTum, "out.txt: cannot format trajectory: TUM stamp 1 (1) does not increase");
  expect_write_error(kGraph, "graph id v1 is repeated");
  t.stamps = {0.5, 1.0};
  expect_write_error(kGraph, "graph stamp 0 (0.5) is not an integer id");
  t.stamps = {0.0};
  expect_write_error(kKitti, "1 stamps for 2 poses");
  t.stamps = {0.0, 1.0};
  t.poses[1].translation().x() = std::nan("");
  expect_write_error(kKitti, "pose 1 is not finite");
}

TEST(TrajectoryIoTest, ReadsRealGraph) {
  CARAT_REQUIRE_DATA("kitti07_seq5/graph.txt");
  const Trajectory graph =
      read_trajectory(test::data_dir() / "kitti07_seq5/graph.txt", TrajectoryFormat::kGraph);
  ASSERT_EQ(graph.poses.size(), 5u);
  EXPECT_EQ(graph.stamps, (std::vector<double>{0, 1, 2, 3, 4}));
  EXPECT_LE((graph.poses[4].translation() - Eigen::Vector3d(3.84648, 27.7398, -0.110073)).norm(),
            1e-12);
  // v4 turns about 94.5 degrees, mostly about z.
  const Eigen::AngleAxisd rotation(graph.poses[4].linear());
  EXPECT_NEAR(rotation.angle() * 180.0 / M_PI, 94.547, 1e-3);
  EXPECT_GT(rotation.axis().z(), 0.99);
}

TEST(UmeyamaTest, RecoversRigidTransformFromNoiselessPoints) {
  std::mt19937 rng(3);
  std::normal_distribution<double> normal(0.0, 20.0);
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Isometry3d T = random_pose(rng, 100.0);
    std::vector<Eigen::Vector3d> estimate, reference;
    for (int k = 0; k < 3 + trial; ++k) {
      estimate.emplace_back(normal(rng), normal(rng), normal(rng));
      reference.push_back(T * estimate.back());
    }
    const Eigen::Isometry3d found = align_umeyama(estimate, reference);
    EXPECT_LE((found.matrix() - T.matrix()).cwiseAbs().maxCoeff(), 1e-9) << "trial " << trial;
  }
}

TEST(UmeyamaTest, DegenerateConfigurationsGiveFiniteRotations) {
  std::mt19937 rng(5);
  const Eigen::Isometry3d T = random_pose(rng);
  // Collinear points: the rotation about the line is free, but the points still map exactly.
  std::vector<Eigen::Vector3d> estimate, reference;
  for (int k = 0; k < 6; ++k) {
    estimate.push_back(Eigen::Vector3d(1, 2, 3) + k * Eigen::Vector3d(0.3, -0.2, 0.9));
    reference.push_back(T * estimate.back());
  }
  Eigen::Isometry3d found = align_umeyama(estimate, reference);
  ASSERT_TRUE(found.matrix().allFinite());
  EXPECT_NEAR(found.linear().determinant(), 1.0, 1e-12);
  EXPECT_LE((found.linear().transpose() * found.linear() - Eigen::Matrix3d::Identity()).norm(),
            1e-12);
  for (std::size_t k = 0; k < estimate.size(); ++k) {
    EXPECT_LE((found * estimate[k] - reference[k]).norm(), 1e-9);
  }
  // Coincident points: identity rotation, translation between the two points.
  estimate.assign(4, Eigen::Vector3d(1, 2, 3));
  reference.assign(4, Eigen::Vector3d(-1, 5, 0));
  found = align_umeyama(estimate, reference);
  EXPECT_TRUE(found.linear().isIdentity(0.0));
  EXPECT_LE((found.translation() - Eigen::Vector3d(-2, 3, -3)).norm(), 1e-12);
  // All zero, and huge coordinates: finite.
  estimate.assign(3, Eigen::Vector3d::Zero());
  reference.assign(3, Eigen::Vector3d::Zero());
  EXPECT_TRUE(align_umeyama(estimate, reference).matrix().isIdentity(0.0));
  estimate = {{1e300, 0, 0}, {0, -1e300, 0}, {0, 0, 1e300}};
  reference = {{-1e300, 0, 0}, {0, 1e300, 0}, {0, 0, 1e300}};
  found = align_umeyama(estimate, reference);
  EXPECT_TRUE(found.matrix().allFinite());
  for (int k = 0; k < 3; ++k) {
    EXPECT_LE((found * estimate[k] - reference[k]).lpNorm<Eigen::Infinity>() / 1e300, 1e-12);
  }
}

TEST(UmeyamaTest, RejectsBadInput) {
  std::vector<Eigen::Vector3d> three(3, Eigen::Vector3d::Ones());
  std::vector<Eigen::Vector3d> two(2, Eigen::Vector3d::Ones());
  EXPECT_THROW(align_umeyama(two, two), Error);
  EXPECT_THROW(align_umeyama(three, two), Error);
  auto bad = three;
  bad[1].y() = std::numeric_limits<double>::infinity();
  EXPECT_THROW(align_umeyama(bad, three), Error);
  EXPECT_THROW(align_umeyama(three, bad), Error);
}

TEST(AteTest, AlignedTransformedTrajectoryHasZeroError) {
  std::mt19937 rng(11);
  const Eigen::Isometry3d T = random_pose(rng, 50.0);
  std::vector<Eigen::Isometry3d> reference, estimate;
  for (int k = 0; k < 30; ++k) {
    reference.push_back(random_pose(rng));
    estimate.push_back(T.inverse() * reference.back());
  }
  const AteStatistics aligned = compute_ate(estimate, reference);
  EXPECT_EQ(aligned.num_poses, 30);
  EXPECT_LE(aligned.rmse, 1e-9);
  EXPECT_LE(aligned.max, 1e-9);
  EXPECT_LE(aligned.rotation_max_deg, 1e-6);
  EXPECT_LE((aligned.T_reference_estimate.matrix() - T.matrix()).cwiseAbs().maxCoeff(), 1e-9);
  const AteStatistics raw = compute_ate(estimate, reference, {.align = false});
  EXPECT_GT(raw.rmse, 1.0);
  EXPECT_TRUE(raw.T_reference_estimate.matrix().isIdentity(0.0));
}

TEST(AteTest, ConstantShift) {
  std::mt19937 rng(13);
  const Eigen::Vector3d shift(0.3, -1.2, 0.4);  // |shift| = 1.3
  std::vector<Eigen::Isometry3d> reference, estimate;
  for (int k = 0; k < 10; ++k) {
    reference.push_back(random_pose(rng));
    estimate.push_back(reference.back());
    estimate.back().translation() += shift;
  }
  const AteStatistics raw = compute_ate(estimate, reference, {.align = false});
  for (double value : {raw.rmse, raw.mean, raw.median, raw.min, raw.max}) {
    EXPECT_NEAR(value, 1.3, 1e-12);
  }
  EXPECT_NEAR(raw.std, 0.0, 1e-12);
  EXPECT_NEAR(raw.rotation_max_deg, 0.0, 1e-6);
  const AteStatistics aligned = compute_ate(estimate, reference);
  EXPECT_LE(aligned.rmse, 1e-9);
  EXPECT_LE((aligned.T_reference_estimate.translation() + shift).norm(), 1e-9);
}

TEST(AteTest, HandComputedStatistics) {
  std::vector<Eigen::Isometry3d> reference(4, Eigen::Isometry3d::Identity());
  std::vector<Eigen::Isometry3d> estimate(4, Eigen::Isometry3d::Identity());
  const double offsets[4] = {3, 1, 4, 2};  // errors 1, 2, 3, 4 in some order
  const Eigen::Vector3d direction = Eigen::Vector3d(1, 2, 2) / 3.0;
  for (int k = 0; k < 4; ++k) {
    reference[k].translation() = Eigen::Vector3d(k, -k, 2 * k);
    estimate[k].translation() = reference[k].translation() + offsets[k] * direction;
  }
  AteStatistics s = compute_ate(estimate, reference, {.align = false});
  EXPECT_NEAR(s.mean, 2.5, 1e-12);
  EXPECT_NEAR(s.median, 2.5, 1e-12);
  EXPECT_NEAR(s.rmse, std::sqrt(7.5), 1e-12);
  EXPECT_NEAR(s.std, std::sqrt(1.25), 1e-12);
  EXPECT_NEAR(s.min, 1.0, 1e-12);
  EXPECT_NEAR(s.max, 4.0, 1e-12);
  EXPECT_EQ(s.num_poses, 4);
  // Odd count: the median is the middle value.
  s = compute_ate(std::span(estimate).first(3), std::span(reference).first(3), {.align = false});
  EXPECT_NEAR(s.median, 3.0, 1e-12);  // errors 3, 1, 4
  // One pose without alignment is fine.
  s = compute_ate(std::span(estimate).first(1), std::span(reference).first(1), {.align = false});
  EXPECT_NEAR(s.rmse, 3.0, 1e-12);
  EXPECT_NEAR(s.std, 0.0, 1e-12);
}

TEST(AteTest, RotationErrorInDegrees) {
  std::mt19937 rng(17);
  const Eigen::Matrix3d turn =
      Eigen::AngleAxisd(10.0 * M_PI / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  std::vector<Eigen::Isometry3d> reference, estimate;
  for (int k = 0; k < 8; ++k) {
    reference.push_back(random_pose(rng));
    estimate.push_back(reference.back());
    estimate.back().linear() = reference.back().linear() * turn;
  }
  const AteStatistics s = compute_ate(estimate, reference, {.align = false});
  EXPECT_NEAR(s.rmse, 0.0, 1e-12);
  EXPECT_NEAR(s.rotation_rmse_deg, 10.0, 1e-9);
  EXPECT_NEAR(s.rotation_mean_deg, 10.0, 1e-9);
  EXPECT_NEAR(s.rotation_max_deg, 10.0, 1e-9);
}

TEST(AteTest, RejectsBadInput) {
  const std::vector<Eigen::Isometry3d> three(3, Eigen::Isometry3d::Identity());
  const std::vector<Eigen::Isometry3d> four(4, Eigen::Isometry3d::Identity());
  try {
    (void)compute_ate(three, four);
    FAIL() << "no error";
  } catch (const Error& error) {
    EXPECT_NE(std::string(error.what()).find("estimate has 3 poses but the reference has 4"),
              std::string::npos)
        << error.what();
  }
  EXPECT_THROW(compute_ate({}, {}), Error);
  EXPECT_THROW(compute_ate(std::span(three).first(2), std::span(three).first(2)), Error);
  auto bad = three;
  bad[2].translation().z() = std::nan("");
  EXPECT_THROW(compute_ate(bad, three, {.align = false}), Error);
  EXPECT_THROW(compute_ate(three, bad, {.align = false}), Error);
}

TEST(AssociateTest, PairsClosestStampsOnce) {
  using Pairs = std::vector<std::pair<int, int>>;
  const std::vector<double> a = {0.0, 0.1, 0.2, 0.3};
  EXPECT_EQ(associate_by_stamp(a, a), (Pairs{{0, 0}, {1, 1}, {2, 2}, {3, 3}}));
  // Within tolerance, reference unsorted.
  EXPECT_EQ(associate_by_stamp(a, std::vector<double>{0.305, 0.004, 0.5, 0.195}),
            (Pairs{{0, 1}, {2, 3}, {3, 0}}));
  // The nearer estimate wins the reference stamp; the other stays unpaired.
  EXPECT_EQ(associate_by_stamp(std::vector<double>{1.0, 1.007}, std::vector<double>{1.006}),
            (Pairs{{1, 0}}));
  // Ties go to the lower estimate index.
  EXPECT_EQ(associate_by_stamp(std::vector<double>{1.0, 2.0}, std::vector<double>{1.5}, 0.5),
            (Pairs{{0, 0}}));
  // The bound is inclusive; farther stamps are not paired.
  EXPECT_EQ(associate_by_stamp(std::vector<double>{0.5}, std::vector<double>{0.25}, 0.25),
            (Pairs{{0, 0}}));
  EXPECT_TRUE(associate_by_stamp(std::vector<double>{0.0}, std::vector<double>{0.02}).empty());
  EXPECT_TRUE(associate_by_stamp({}, a).empty());
  // Repeated reference stamps are each used once.
  EXPECT_EQ(associate_by_stamp(std::vector<double>{5.0, 5.0, 5.0}, std::vector<double>{5.0, 5.0}),
            (Pairs{{0, 0}, {1, 1}}));
}

// The association as first written (every candidate listed, sorted and scanned greedily), kept
// verbatim as the oracle of the heap-based associate_by_stamp().
std::vector<std::pair<int, int>> associate_by_stamp_brute_force(
    std::span<const double> estimate_stamps, std::span<const double> reference_stamps,
    double max_difference) {
  std::vector<int> order(reference_stamps.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return reference_stamps[a] < reference_stamps[b]; });
  std::vector<double> sorted(order.size());
  for (std::size_t k = 0; k < order.size(); ++k) sorted[k] = reference_stamps[order[k]];

  struct Candidate {
    double difference;
    int estimate;
    int reference;
  };
  std::vector<Candidate> candidates;
  for (std::size_t e = 0; e < estimate_stamps.size(); ++e) {
    const double stamp = estimate_stamps[e];
    auto j = static_cast<std::size_t>(
        std::lower_bound(sorted.begin(), sorted.end(), stamp - max_difference) - sorted.begin());
    // stamp - max_difference is rounded: step back over any neighbour that still qualifies.
    while (j > 0 && std::abs(stamp - sorted[j - 1]) <= max_difference) --j;
    for (; j < sorted.size() && !(sorted[j] - stamp > max_difference); ++j) {
      const double difference = std::abs(stamp - sorted[j]);
      if (difference <= max_difference) {
        candidates.push_back({difference, static_cast<int>(e), order[j]});
      }
    }
  }
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
    return std::tie(a.difference, a.estimate, a.reference) <
           std::tie(b.difference, b.estimate, b.reference);
  });
  std::vector<char> estimate_used(estimate_stamps.size(), 0);
  std::vector<char> reference_used(reference_stamps.size(), 0);
  std::vector<std::pair<int, int>> pairs;
  for (const Candidate& c : candidates) {
    if (estimate_used[c.estimate] || reference_used[c.reference]) continue;
    estimate_used[c.estimate] = 1;
    reference_used[c.reference] = 1;
    pairs.emplace_back(c.estimate, c.reference);
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

// Compares associate_by_stamp() with the brute-force oracle on random stamps drawn from `values`
// (so that equal stamps and equal differences are frequent), in random order, for n and m in
// 0..40 and several bounds.
void expect_association_matches_brute_force(const std::vector<double>& values,
                                            const std::vector<double>& max_differences,
                                            int num_seeds) {
  for (int seed = 0; seed < num_seeds; ++seed) {
    std::mt19937 rng(static_cast<unsigned>(seed));
    std::uniform_int_distribution<int> count(0, 40);
    std::uniform_int_distribution<std::size_t> pick(0, values.size() - 1);
    const auto draw = [&] {
      std::vector<double> stamps(static_cast<std::size_t>(count(rng)));
      for (double& stamp : stamps) stamp = values[pick(rng)];
      // Now and then sorted (as trajectory files are), otherwise in random order.
      if (seed % 4 == 0) std::sort(stamps.begin(), stamps.end());
      return stamps;
    };
    const std::vector<double> estimate = draw();
    const std::vector<double> reference = draw();
    for (double max_difference : max_differences) {
      ASSERT_EQ(associate_by_stamp(estimate, reference, max_difference),
                associate_by_stamp_brute_force(estimate, reference, max_difference))
          << "seed " << seed << ", max_difference " << max_difference;
    }
  }
}

TEST(AssociateTest, StampsMatchBruteForceGreedyWithTies) {
  // Multiples of 0.25 on a small grid: many equal stamps and equal (exact) differences.
  std::vector<double> values;
  for (int k = -6; k <= 14; ++k) values.push_back(0.25 * k);
  expect_association_matches_brute_force(values, {0.0, 0.25, 0.3, 0.5, 0.75, 1.0, 2.5, 1e9}, 3000);
  // A narrow grid: whole runs of stamps differ by the same amount.
  expect_association_matches_brute_force({0.0, 0.25, 0.5, 0.75}, {0.0, 0.25, 0.5, 1e9}, 1000);
}

TEST(AssociateTest, StampsMatchBruteForceGreedyWithRoundingTies) {
  // Stamps a fraction of an ulp of the difference apart: unequal gaps whose rounded differences
  // tie (|0.5 - (-0.5 - 2^-53)| rounds to 1, as does |0.5 + 2^-53 - (-0.5)|, but not both ends).
  const double tiny = std::ldexp(1.0, -53);
  std::vector<double> values = {-1.5,           -0.5 - tiny,    -0.5,   -0.5 + tiny / 2, 0.0,
                                tiny,           0.5 - tiny / 2, 0.5,    0.5 + tiny,      1.5,
                                1.5 + 2 * tiny, 1e-300,         -1e-300};
  expect_association_matches_brute_force(values, {0.0, 1.0, 1.0 + 2 * tiny, 2.0, 1e9}, 3000);
}

TEST(AssociateTest, StampsScaleWithoutListingCandidates) {
  // 200,000 poses each and a bound that admits all 4e10 pairs: the candidates would need ~640 GB.
  // Estimate k is at 2 (n - 1 - k), reference j at 2 j + 1: every neighbour differs by 1, so the
  // tie rule decides it all. Estimate k < n - 1 takes reference n - 2 - k (the lower of its two
  // neighbours); estimate n - 1 (at 0) finds both of its neighbours taken and gets the last one.
  constexpr int n = 200000;
  std::vector<double> estimate(n), reference(n);
  for (int k = 0; k < n; ++k) {
    estimate[k] = 2.0 * (n - 1 - k);
    reference[k] = 2.0 * k + 1.0;
  }
  const auto pairs = associate_by_stamp(estimate, reference, 1e9);
  ASSERT_EQ(pairs.size(), static_cast<std::size_t>(n));
  EXPECT_EQ(pairs[0], std::make_pair(0, n - 2));
  EXPECT_EQ(pairs[1], std::make_pair(1, n - 3));
  EXPECT_EQ(pairs[n / 2], std::make_pair(n / 2, n - 2 - n / 2));
  EXPECT_EQ(pairs[n - 2], std::make_pair(n - 2, 0));
  EXPECT_EQ(pairs[n - 1], std::make_pair(n - 1, n - 1));
  for (int k = 0; k + 1 < n; ++k) ASSERT_EQ(pairs[k], std::make_pair(k, n - 2 - k));
  // Shuffled stamps with unrelated spacing: all paired, each with its nearest partner.
  std::mt19937 rng(7);
  std::vector<int> permutation(n);
  std::iota(permutation.begin(), permutation.end(), 0);
  std::shuffle(permutation.begin(), permutation.end(), rng);
  for (int k = 0; k < n; ++k) {
    estimate[k] = 0.1 * k;
    reference[permutation[k]] = 0.1 * k + 0.003;
  }
  const auto shuffled = associate_by_stamp(estimate, reference, 1e9);
  ASSERT_EQ(shuffled.size(), static_cast<std::size_t>(n));
  for (int k = 0; k < n; k += 9973) EXPECT_EQ(shuffled[k], std::make_pair(k, permutation[k]));
}

TEST(AssociateTest, RejectsBadInput) {
  const std::vector<double> a = {0.0, 1.0};
  EXPECT_THROW(associate_by_stamp(a, a, -0.1), Error);
  EXPECT_THROW(associate_by_stamp(a, a, std::nan("")), Error);
  EXPECT_THROW(associate_by_stamp(std::vector<double>{std::nan("")}, a), Error);
  EXPECT_THROW(associate_by_stamp(a, std::vector<double>{0.0, HUGE_VAL}), Error);
}

Eigen::Isometry3d pose(double yaw, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = t;
  return T;
}

TEST(AteTest, CollinearPositionsTakeTheRotationAboutTheirLineFromOrientations) {
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
