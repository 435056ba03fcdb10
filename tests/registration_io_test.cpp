// PCD and PLY reading and writing: round trips in every format, malformed files with their
// messages, and the small_gicp PLY pair.
#include <gtest/gtest.h>

#include <fstream>

#include "carat/registration/point_cloud_io.hpp"
#include "carat/solver/error.hpp"
#include "test_support.hpp"

namespace carat {
namespace {

PointCloud sample_cloud() {
  PointCloud cloud;
  for (int i = 0; i < 100; ++i) cloud.points.emplace_back(0.5f * i, -0.25f * i, 3.0f + 0.125f * i);
  return cloud;
}

void write_text(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

void expect_error(const std::function<void()>& f, const std::string& fragment) {
  try {
    f();
    FAIL() << "expected an error containing: " << fragment;
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
  }
}

TEST(PointCloudIoTest, RoundTripsInEveryFormat) {
  const auto dir = test::scratch_dir("pcio");
  const PointCloud cloud = sample_cloud();
  for (bool ascii : {false, true}) {
    write_pcd(dir / "c.pcd", cloud, ascii);
    write_ply(dir / "c.ply", cloud, ascii);
    for (const char* file : {"c.pcd", "c.ply"}) {
      const PointCloud back = read_point_cloud(dir / file);
      ASSERT_EQ(back.size(), cloud.size()) << file;
      for (std::size_t i = 0; i < cloud.size(); ++i)
        EXPECT_EQ(back.points[i], cloud.points[i]) << file << " " << i;
    }
  }
}

TEST(PointCloudIoTest, PcdWithExtraFieldsAndDoubles) {
  const auto dir = test::scratch_dir("pcd_fields");
  write_text(dir / "a.pcd",
             "VERSION 0.7\nFIELDS intensity x y z rgb\nSIZE 4 8 8 8 4\nTYPE F F F F U\nCOUNT 1 1 1 "
             "1 1\nWIDTH 2\nHEIGHT 1\n"
             "POINTS 2\nDATA ascii\n7 1 2 3 0\n8 4 5 6 0\n");
  const PointCloud a = read_pcd(dir / "a.pcd");
  ASSERT_EQ(a.size(), 2u);
  EXPECT_EQ(a.points[1], Eigen::Vector3f(4, 5, 6));
}

TEST(PointCloudIoTest, MalformedFilesAreClearErrors) {
  const auto dir = test::scratch_dir("pcio_bad");
  const std::string header =
      "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 3\nHEIGHT 1\nPOINTS "
      "3\n";
  write_text(dir / "short.pcd", header + "DATA binary\n" + std::string(20, '\0'));
  expect_error([&] { read_pcd(dir / "short.pcd"); },
               "truncated: header announces 3 points of 12 bytes");
  write_text(dir / "short_ascii.pcd", header + "DATA ascii\n1 2 3\n4 5 6\n");
  expect_error([&] { read_pcd(dir / "short_ascii.pcd"); },
               "truncated: header announces 3 points, found 2");
  write_text(dir / "compressed.pcd", header + "DATA binary_compressed\n");
  expect_error([&] { read_pcd(dir / "compressed.pcd"); },
               "DATA binary_compressed is not supported");
  write_text(dir / "noz.pcd", "FIELDS x y\nSIZE 4 4\nTYPE F F\nPOINTS 1\nDATA ascii\n1 2\n");
  expect_error([&] { read_pcd(dir / "noz.pcd"); }, "no 'z' field");
  write_text(dir / "type.pcd",
             "FIELDS x y z\nSIZE 4 4 4\nTYPE F Q F\nPOINTS 1\nDATA ascii\n1 2 3\n");
  expect_error([&] { read_pcd(dir / "type.pcd"); }, "unknown TYPE 'Q'");
  write_text(dir / "nan.pcd",
             "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 2\nDATA ascii\n1 2 3\nnan 1 1\n");
  expect_error([&] { read_pcd(dir / "nan.pcd"); }, "point 1 is not finite");
  ReadOptions drop;
  drop.drop_non_finite = true;
  EXPECT_EQ(read_pcd(dir / "nan.pcd", drop).size(), 1u);
  write_text(dir / "empty.pcd", "");
  expect_error([&] { read_pcd(dir / "empty.pcd"); }, "empty file");
  write_text(dir / "notply.ply", "plx\n");
  expect_error([&] { read_ply(dir / "notply.ply"); }, "not a PLY file");
  write_text(dir / "big.ply",
             "ply\nformat binary_big_endian 1.0\nelement vertex 1\nproperty float x\nproperty "
             "float y\nproperty float z\nend_header\n");
  expect_error([&] { read_ply(dir / "big.ply"); }, "binary_big_endian PLY is not supported");
  write_text(dir / "trunc.ply",
             "ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty float x\nproperty "
             "float y\nproperty float z\nend_header\n" +
                 std::string(13, '\0'));
  expect_error([&] { read_ply(dir / "trunc.ply"); },
               "truncated: header announces 5 points of 12 bytes");
  write_text(dir / "noend.ply", "ply\nformat ascii 1.0\nelement vertex 1\n");
  expect_error([&] { read_ply(dir / "noend.ply"); }, "truncated header (no end_header)");
  write_text(dir / "list.ply",
             "ply\nformat ascii 1.0\nelement vertex 1\nproperty list uchar int idx\nend_header\n");
  expect_error([&] { read_ply(dir / "list.ply"); },
               "list properties on vertices are not supported");
  expect_error([&] { read_point_cloud(dir / "x.xyz"); }, "unsupported file type '.xyz'");
}

TEST(PointCloudIoTest, SmallGicpPairReads) {
  CARAT_REQUIRE_DATA("smallgicp_pair/source.ply");
  const PointCloud source = read_ply(test::data_dir() / "smallgicp_pair/source.ply");
  EXPECT_EQ(source.size(), 69792u);
  std::size_t zeros = 0;
  for (const auto& p : source.points) zeros += p.isZero() ? 1 : 0;
  EXPECT_GT(zeros, 5000u);
  EXPECT_LT(zeros, 5300u);
}

}  // namespace
}  // namespace carat
