// Overlap: the fraction of a cloud's points that fall in another's occupied voxels.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <random>
#include <set>

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

}  // namespace
}  // namespace carat
