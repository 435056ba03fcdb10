// Overlap: the fraction of a cloud's points that fall in another's occupied voxels.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

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

}  // namespace
}  // namespace carat
