// Cloud and scan I/O: PCD, PLY and KITTI .bin reading and writing, round trips in every
// format, malformed files with their messages, and the small_gicp PLY pair.
#include <gtest/gtest.h>

#include <fstream>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/registration/io/kitti_io.hpp"
#include "carat/registration/io/point_cloud_io.hpp"
#include "test_support.hpp"

namespace carat {
namespace {

PointCloud sample_cloud() {
  PointCloud cloud;
  for (int i = 0; i < 100; ++i) {
    const auto f = static_cast<float>(i);
    cloud.points.emplace_back(0.5f * f, -0.25f * f, 3.0f + 0.125f * f);
  }
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

// read_point_cloud() picks the reader by the extension: a cloud written by each writer comes back
// the same (.bin in both record layouts), and any other extension is one error naming the file
// and the formats.
TEST(PointCloudIoTest, ReadPointCloudDispatchesOnTheExtension) {
  const auto dir = test::scratch_dir("pcio_dispatch");
  const PointCloud cloud = sample_cloud();
  const auto expect_same = [&](const PointCloud& back, const std::string& file) {
    ASSERT_EQ(back.size(), cloud.size()) << file;
    for (std::size_t i = 0; i < cloud.size(); ++i)
      EXPECT_EQ(back.points[i], cloud.points[i]) << file << " " << i;
  };
  write_pcd(dir / "c.pcd", cloud);
  expect_same(read_point_cloud(dir / "c.pcd"), "c.pcd");
  write_ply(dir / "c.ply", cloud);
  expect_same(read_point_cloud(dir / "c.ply"), "c.ply");
  write_kitti_bin(dir / "xyzi.bin", cloud, KittiFormat::kXyzi);
  expect_same(read_point_cloud(dir / "xyzi.bin", KittiFormat::kXyzi), "xyzi.bin");
  write_kitti_bin(dir / "xyz.bin", cloud, KittiFormat::kXyz);
  expect_same(read_point_cloud(dir / "xyz.bin", KittiFormat::kXyz), "xyz.bin");
  // The layout option matters for .bin only: 100 records of 12 bytes are 75 of 16.
  EXPECT_EQ(read_point_cloud(dir / "xyz.bin", KittiFormat::kXyzi).size(), 75u);
  for (const char* file : {"c.xyz", "c.PCD", "c"}) {
    std::filesystem::copy_file(dir / "c.pcd", dir / file);
    try {
      read_point_cloud(dir / file);
      ADD_FAILURE() << file << " was read";
    } catch (const Error& e) {
      const std::string ext = std::filesystem::path(file).extension().string();
      EXPECT_EQ(std::string(e.what()), (dir / file).string() + ": unsupported file type '" + ext +
                                           "' (expected .pcd, .ply or .bin)");
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

// Header numbers become sizes and offsets only after checked arithmetic: counts whose product or
// sum wraps size_t (the crash class of SIZE x COUNT), counts beyond 2^64, and counts that lie.
TEST(PointCloudIoTest, HeaderNumbersThatOverflowAreErrors) {
  const auto pcd = [](const std::string& size, const std::string& count, const std::string& points,
                      const std::string& data) {
    return "VERSION 0.7\nFIELDS x y z\nSIZE " + size + "\nTYPE F F F\nCOUNT " + count +
           "\nPOINTS " + points + "\nDATA " + data;
  };
  const std::string payload(24, 'A');
  // 4 x 2^62 = 2^64 wraps to 0: the record would be 8 bytes and x read out of bounds.
  expect_error(
      [&] {
        parse_pcd(pcd("4 4 4", "4611686018427387904 1 1", "2", "binary\n") + payload, "w.pcd");
      },
      "w.pcd: the size of field 'x' overflows");
  expect_error(
      [&] { parse_pcd(pcd("4 4 4", "1 18446744073709551615 1", "2", "ascii\n1 2 3\n"), "a.pcd"); },
      "a.pcd: the size of field 'y' overflows");
  expect_error(
      [&] {
        parse_pcd(pcd("1 1 1", "9223372036854775808 9223372036854775808 1", "1", "binary\n"),
                  "s.pcd");
      },
      "s.pcd: a point record of more than 1048576 bytes");
  expect_error(
      [&] { parse_pcd(pcd("4 4 4", "1 1 18446744073709551616", "1", "ascii\n"), "o.pcd"); },
      "o.pcd: COUNT '18446744073709551616' is out of range");
  expect_error([&] { parse_pcd(pcd("4 4 4", "1 1 1", "-1", "ascii\n"), "n.pcd"); },
               "n.pcd: cannot read POINTS from '-1'");
  expect_error(
      [&] {
        parse_pcd(pcd("4 4 4", "1 1 1", "18446744073709551615", "binary\n") + payload, "p.pcd");
      },
      "p.pcd: announces 18446744073709551615 points, more than the 100000000 carat reads");
  // POINTS within the limit but more than the data: the division check, never a wrap.
  expect_error([&] { parse_pcd(pcd("4 4 4", "1 1 1", "99999999", "binary\n") + payload, "l.pcd"); },
               "l.pcd: truncated: header announces 99999999 points of 12 bytes, the file holds 24");
  expect_error(
      [&] {
        parse_pcd(
            "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 4294967296\nHEIGHT 4294967296\nPOINTS "
            "0\nDATA ascii\n",
            "wh.pcd");
      },
      "wh.pcd: WIDTH x HEIGHT overflows");
  expect_error(
      [&] {
        parse_pcd(
            "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 3\nHEIGHT 1\nPOINTS 2\nDATA ascii\n1 2 "
            "3\n4 5 6\n",
            "m.pcd");
      },
      "m.pcd: WIDTH 3 x HEIGHT 1 does not equal POINTS 2");
  expect_error(
      [&] {
        parse_pcd("FIELDS x y z\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 0\nDATA ascii\n",
                  "d.pcd");
      },
      "d.pcd: header line FIELDS appears twice");
  expect_error(
      [&] {
        parse_pcd("FIELDS x y x z\nSIZE 4 4 4 4\nTYPE F F F F\nPOINTS 0\nDATA ascii\n", "x.pcd");
      },
      "x.pcd: field 'x' is declared twice");
  expect_error(
      [&] { parse_pcd("FIELDS x y z\nSIZE 2 4 4\nTYPE F F F\nPOINTS 0\nDATA ascii\n", "h.pcd"); },
      "h.pcd: field 'x' has an unsupported type F2");
  // Raw bytes in a header are never copied into a message.
  const std::string message = [&] {
    try {
      parse_pcd("FIELDS x y z\nSIZE 4 4 4\nTYPE F \x01\x02\x7f F\n", "b.pcd");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  }();
  EXPECT_EQ(message, "b.pcd: unknown TYPE '??\?'");
  const auto ply = [](const std::string& count, const std::string& format) {
    return "ply\nformat " + format + " 1.0\nelement vertex " + count +
           "\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
  };
  expect_error(
      [&] { parse_ply(ply("4611686018427387904", "binary_little_endian") + payload, "v.ply"); },
      "v.ply: announces 4611686018427387904 points, more than the 100000000");
  expect_error([&] { parse_ply(ply("18446744073709551616", "ascii"), "o.ply"); },
               "o.ply: the vertex count '18446744073709551616' is out of range");
  expect_error([&] { parse_ply(ply("99999999", "binary_little_endian") + payload, "t.ply"); },
               "t.ply: truncated: header announces 99999999 points of 12 bytes");
  ReadOptions small;
  small.max_points = 1;
  expect_error([&] { parse_ply(ply("2", "binary_little_endian") + payload, "c.ply", small); },
               "c.ply: announces 2 points, more than the 1 carat reads from one file");
  EXPECT_EQ(parse_ply(ply("2", "binary_little_endian") + payload, "ok.ply").size(), 2u);
}

TEST(PointCloudIoTest, OnlyRegularFilesAndTheyAreReadInChunks) {
  expect_error([] { read_pcd("/dev/zero"); },
               "/dev/zero: is a character device, not a regular file");
  expect_error([] { read_ply("/dev/zero"); },
               "/dev/zero: is a character device, not a regular file");
  expect_error([] { read_kitti_bin("/dev/zero", KittiFormat::kXyz); },
               "/dev/zero: is a character device, not a regular file");
  const auto dir = test::scratch_dir("pcio_chunks");
  expect_error([&] { read_pcd(dir); }, "is a directory, not a file");
  // More points than one chunk holds, in every format: the same cloud back.
  PointCloud cloud;
  for (int i = 0; i < 200000; ++i)
    cloud.points.emplace_back(0.001f * static_cast<float>(i), -0.5f * static_cast<float>(i % 7),
                              1.0f);
  write_pcd(dir / "big.pcd", cloud);
  write_ply(dir / "big.ply", cloud);
  write_kitti_bin(dir / "big.bin", cloud, KittiFormat::kXyzi);
  for (const char* file : {"big.pcd", "big.ply", "big.bin"}) {
    const PointCloud back = read_point_cloud(dir / file);
    ASSERT_EQ(back.size(), cloud.size()) << file;
    EXPECT_EQ(back.points[131071], cloud.points[131071]) << file;
    EXPECT_EQ(back.points.back(), cloud.points.back()) << file;
  }
  ReadOptions small;
  small.max_points = 199999;
  expect_error([&] { read_kitti_bin(dir / "big.bin", KittiFormat::kXyzi, small); },
               "big.bin: holds 200000 points, more than the 199999 carat reads from one file");
}

TEST(KittiFormatTest, NamesRoundTrip) {
  for (KittiFormat format : {KittiFormat::kXyzi, KittiFormat::kXyz}) {
    EXPECT_EQ(parse_kitti_format(to_string(format)), format) << to_string(format);
  }
  EXPECT_STREQ(to_string(KittiFormat::kXyzi), "xyzi");
  EXPECT_STREQ(to_string(KittiFormat::kXyz), "xyz");
  EXPECT_EQ(test::error_of([] { parse_kitti_format("xyzrgb"); }),
            "unknown KITTI .bin format 'xyzrgb' (valid: xyzi, xyz)");
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

TEST(KittiTest, ReadsAndRejectsMalformedFiles) {
  const auto dir = test::scratch_dir("kitti");
  const std::vector<float> xyzi = {1, 2, 3, 0.5f, 4, 5, 6, 0.25f};
  {
    std::ofstream out(dir / "ok.bin", std::ios::binary);
    out.write(reinterpret_cast<const char*>(xyzi.data()),
              static_cast<std::streamsize>(xyzi.size() * sizeof(float)));
  }
  const PointCloud cloud = read_kitti_bin(dir / "ok.bin", KittiFormat::kXyzi);
  ASSERT_EQ(cloud.size(), 2u);
  EXPECT_EQ(cloud.points[1], Eigen::Vector3f(4, 5, 6));
  // 32 bytes are also a whole number of... no: 32 is not a multiple of 12.
  try {
    read_kitti_bin(dir / "ok.bin", KittiFormat::kXyz);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("32 bytes is not a whole number of 12-byte records"),
              std::string::npos);
  }
  { std::ofstream out(dir / "empty.bin", std::ios::binary); }
  EXPECT_THROW(read_kitti_bin(dir / "empty.bin", KittiFormat::kXyz), Error);
  EXPECT_THROW(read_kitti_bin(dir / "missing.bin", KittiFormat::kXyz), Error);
  const std::vector<float> bad = {1, 2, 3, std::nanf(""), 5, 6};
  {
    std::ofstream out(dir / "nan.bin", std::ios::binary);
    out.write(reinterpret_cast<const char*>(bad.data()),
              static_cast<std::streamsize>(bad.size() * sizeof(float)));
  }
  try {
    read_kitti_bin(dir / "nan.bin", KittiFormat::kXyz);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), (dir / "nan.bin").string() + ": point 1 is not finite");
  }
  ReadOptions drop;
  drop.drop_non_finite = true;
  EXPECT_EQ(read_kitti_bin(dir / "nan.bin", KittiFormat::kXyz, drop).size(), 1u);
}

}  // namespace
}  // namespace carat
