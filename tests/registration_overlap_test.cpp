// Overlap: the fraction of a cloud's points that fall in another's occupied voxels.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <random>
#include <set>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/registration/overlap.hpp"
#include "carat/registration/point_cloud.hpp"

namespace carat {
namespace {

TEST(OverlapTest, FractionOfOccupiedVoxels) {
  PointCloud cloud;
  for (int x = 0; x < 10; ++x)
    for (int y = 0; y < 10; ++y)
      cloud.points.emplace_back(static_cast<float>(x) + 0.5f, static_cast<float>(y) + 0.5f, 0.5f);
  const VoxelOccupancy occupancy(cloud, 1.0);
  EXPECT_EQ(occupancy.size(), 100u);
  EXPECT_DOUBLE_EQ(overlap_fraction(occupancy, cloud, Eigen::Isometry3d::Identity()), 1.0);
  Eigen::Isometry3d half = Eigen::Isometry3d::Identity();
  half.translation() = Eigen::Vector3d(5.0, 0.0, 0.0);  // half the source leaves the grid
  EXPECT_DOUBLE_EQ(overlap_fraction(occupancy, cloud, half), 0.5);
  EXPECT_DOUBLE_EQ(overlap_fraction(occupancy, cloud, half, 2), 0.5);
  EXPECT_DOUBLE_EQ(overlap_fraction(occupancy, PointCloud{}, half), 0.0);
  EXPECT_THROW(VoxelOccupancy(cloud, 0.0), Error);
  cloud.points.emplace_back(std::nanf(""), 0.0f, 0.0f);
  EXPECT_THROW(VoxelOccupancy(cloud, 1.0), Error);
}

TEST(OverlapTest, CompactAndScatteredCloudsAnswerAsTheirVoxels) {
  // A compact scan (its occupied voxels fill their box densely) and the same scan with a few
  // points a kilometre away (a sparse box): both must answer exactly as the set of their voxels.
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-20.0f, 20.0f);
  PointCloud compact;
  for (int k = 0; k < 3000; ++k) compact.points.emplace_back(u(rng), u(rng), 0.1f * u(rng));
  PointCloud scattered = compact;
  scattered.points.emplace_back(1000.0f, -1000.0f, 5.0f);
  scattered.points.emplace_back(-1000.0f, 1000.0f, -5.0f);
  for (const double size : {1.0, 0.3}) {
    for (const PointCloud* cloud : {&compact, &scattered}) {
      const VoxelOccupancy occupancy(*cloud, size);
      std::set<std::array<double, 3>> voxels;
      for (const auto& p : cloud->points) {
        voxels.insert({std::floor(static_cast<double>(p.x()) * (1.0 / size)),
                       std::floor(static_cast<double>(p.y()) * (1.0 / size)),
                       std::floor(static_cast<double>(p.z()) * (1.0 / size))});
      }
      EXPECT_EQ(occupancy.size(), voxels.size());
      std::uniform_real_distribution<double> probe(-25.0, 25.0);
      int hits = 0;
      for (int k = 0; k < 20000; ++k) {
        // Probes near the points (half of them on one), beyond the box, and on voxel borders.
        Eigen::Vector3d p(probe(rng), probe(rng), 0.2 * probe(rng));
        if (k % 2 == 0) p = cloud->point(static_cast<std::size_t>(k) % cloud->size());
        if (k % 7 == 0) p = (p * (1.0 / size)).array().round().matrix() * size;
        const std::array<double, 3> key = {std::floor(p.x() * (1.0 / size)),
                                           std::floor(p.y() * (1.0 / size)),
                                           std::floor(p.z() * (1.0 / size))};
        const bool expected = voxels.count(key) > 0;
        ASSERT_EQ(occupancy.occupied(p), expected) << "probe " << k << " voxel " << size;
        hits += expected ? 1 : 0;
      }
      EXPECT_GT(hits, 8000);  // both answers were exercised
      EXPECT_GT(20000 - hits, 5000);
      EXPECT_EQ(occupancy.occupied(Eigen::Vector3d(1000.0, -1000.0, 5.0)), cloud == &scattered);
      EXPECT_FALSE(occupancy.occupied(Eigen::Vector3d(std::nan(""), 0.0, 0.0)));
      EXPECT_FALSE(occupancy.occupied(Eigen::Vector3d(1e300, 0.0, 0.0)));
      EXPECT_FALSE(occupancy.occupied(Eigen::Vector3d(0.0, -1e7, 0.0)));
    }
  }
  EXPECT_FALSE(VoxelOccupancy(PointCloud{}, 1.0).occupied(Eigen::Vector3d::Zero()));
}

TEST(OverlapTest, CountingAtOnceAnswersAsOnePointAtATime) {
  // count_occupied() inlines the bitmap lookup: over a compact cloud (bitmap) and a scattered one
  // (hash table), poses that put points on voxel borders, outside the box and off the grid, and
  // NaN points, it must count exactly what occupied() answers point by point.
  std::mt19937 rng(41);
  std::uniform_real_distribution<float> u(-20.0f, 20.0f);
  PointCloud compact;
  for (int k = 0; k < 3000; ++k) compact.points.emplace_back(u(rng), u(rng), 0.1f * u(rng));
  PointCloud scattered = compact;
  scattered.points.emplace_back(1000.0f, -1000.0f, 5.0f);
  PointCloud source = compact;
  for (int k = 0; k < 300; ++k)
    source.points.emplace_back(std::round(u(rng)), std::round(u(rng)), 0.0f);  // on borders
  source.points.emplace_back(std::nanf(""), 0.0f, 0.0f);
  source.points.emplace_back(3e9f, 0.0f, 0.0f);
  std::vector<Eigen::Isometry3d> poses(4, Eigen::Isometry3d::Identity());
  poses[1].translation() = Eigen::Vector3d(0.5, -0.25, 0.0);
  poses[2] = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()) * Eigen::Translation3d(7.0, 1.0, 0.1);
  poses[3].translation() = Eigen::Vector3d(35.0, 0.0, 0.0);  // mostly outside the box
  for (const PointCloud* target : {&compact, &scattered}) {
    for (const double size : {1.0, 0.3}) {
      const VoxelOccupancy occupancy(*target, size);
      for (const Eigen::Isometry3d& T : poses) {
        for (const std::size_t stride : {std::size_t{1}, std::size_t{3}}) {
          std::size_t expected = 0, total = 0;
          for (std::size_t i = 0; i < source.size(); i += stride, ++total)
            expected += occupancy.occupied(T * source.point(i)) ? 1 : 0;
          EXPECT_EQ(occupancy.count_occupied(source, T, stride), expected);
          EXPECT_DOUBLE_EQ(overlap_fraction(occupancy, source, T, static_cast<int>(stride)),
                           static_cast<double>(expected) / static_cast<double>(total));
        }
      }
      EXPECT_EQ(occupancy.count_occupied(source, poses[0], 0),
                occupancy.count_occupied(source, poses[0], 1));
    }
  }
}

}  // namespace
}  // namespace carat
