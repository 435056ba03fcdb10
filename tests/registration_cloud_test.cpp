// Cloud preprocessing: the voxel grid, covariance estimation and the k-d tree.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "carat/registration/covariance.hpp"
#include "carat/registration/kdtree.hpp"
#include "carat/registration/voxel_grid.hpp"
#include "test_support.hpp"

namespace carat {
namespace {

TEST(VoxelGridTest, CentroidsPerVoxel) {
  PointCloud cloud;
  cloud.points = {{0.1f, 0.1f, 0.1f}, {0.3f, 0.3f, 0.3f}, {1.5f, 0.2f, 0.2f}, {-0.2f, 0.1f, 0.1f}};
  const PointCloud down = voxel_downsample(cloud, 1.0);
  ASSERT_EQ(down.size(), 3u);
  EXPECT_TRUE(down.points[0].isApprox(Eigen::Vector3f(-0.2f, 0.1f, 0.1f)));
  EXPECT_TRUE(down.points[1].isApprox(Eigen::Vector3f(0.2f, 0.2f, 0.2f)));
  EXPECT_TRUE(down.points[2].isApprox(Eigen::Vector3f(1.5f, 0.2f, 0.2f)));
  EXPECT_THROW(voxel_downsample(cloud, 0.0), Error);
  // Regression (found by the KITTI fuzzer): coordinates far outside the grid are an error, not
  // an undefined float-to-integer conversion.
  cloud.points.push_back({3e38f, 0.0f, 0.0f});
  EXPECT_THROW(voxel_downsample(cloud, 0.5), Error);
}

TEST(VoxelGridTest, SameCentroidsWithAnyNumberOfThreads) {
  // Enough points for the voxels to be split between threads, many sharing a voxel.
  std::mt19937 rng(29);
  std::uniform_real_distribution<float> u(-20.0f, 20.0f);
  PointCloud cloud;
  for (int k = 0; k < 60000; ++k) cloud.points.emplace_back(u(rng), u(rng), 0.05f * u(rng));
  const PointCloud one = voxel_downsample(cloud, 0.5, 1);
  ASSERT_GT(one.size(), 1000u);
  ASSERT_LT(one.size(), cloud.size() / 2);
  for (const int threads : {2, 3, 8}) {
    const PointCloud many = voxel_downsample(cloud, 0.5, threads);
    ASSERT_EQ(many.size(), one.size());
    for (std::size_t i = 0; i < one.size(); ++i) ASSERT_EQ(many.points[i], one.points[i]) << i;
  }
  // Every point in its own voxel: the tables of the parts grow past their first size.
  PointCloud grid;
  for (float x = 0.0f; x < 20.0f; x += 0.5f)
    for (float y = 0.0f; y < 20.0f; y += 0.5f)
      for (float z = 0.0f; z < 10.0f; z += 0.5f) grid.points.emplace_back(x, -y, z + 0.1f);
  const PointCloud grid_one = voxel_downsample(grid, 0.5, 1);
  ASSERT_EQ(grid_one.size(), grid.size());
  for (const int threads : {2, 8}) {
    const PointCloud grid_many = voxel_downsample(grid, 0.5, threads);
    ASSERT_EQ(grid_many.size(), grid.size());
    for (std::size_t i = 0; i < grid.size(); ++i)
      ASSERT_EQ(grid_many.points[i], grid_one.points[i]);
  }
  // The first point off the grid is named, whatever the scheduling.
  cloud.points[41234] = {3e38f, 0.0f, 0.0f};
  cloud.points[50000] = {0.0f, -3e38f, 0.0f};
  try {
    (void)voxel_downsample(cloud, 0.5, 2);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind("point 41234 is too far from the origin", 0), 0u)
        << e.what();
  }
}

TEST(CovarianceTest, PlaneGetsTheRegularizedShape) {
  PointCloud cloud;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int i = 0; i < 500; ++i) cloud.points.emplace_back(u(rng), u(rng), 0.0f);
  const KdTree tree(cloud);
  estimate_covariances(cloud, tree);
  ASSERT_TRUE(cloud.has_covariances());
  for (std::size_t i = 0; i < cloud.size(); i += 50) {
    const Eigen::Matrix3d C = cloud.covariance(i);
    EXPECT_NEAR(C(2, 2), 1e-3, 1e-6);
    EXPECT_NEAR(C(0, 0), 1.0, 1e-6);
    EXPECT_NEAR(C(1, 1), 1.0, 1e-6);
  }
  // Fewer points than k: every neighbourhood is the whole cloud.
  PointCloud small;
  small.points = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}, {0.5f, 0.5f, 0.0f}};
  const KdTree small_tree(small);
  estimate_covariances(small, small_tree);
  EXPECT_NEAR(small.covariance(0)(2, 2), 1e-3, 1e-6);
  PointCloud tiny;
  tiny.points = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const KdTree tiny_tree(tiny);
  try {
    estimate_covariances(tiny, tiny_tree);
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(),
                 "estimate_covariances: a cloud of 3 points is too small (at least 4 are needed)");
  }
}

TEST(KdTreeTest, NearestWithinMatchesBruteForce) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> u(-5.0f, 5.0f);
  PointCloud cloud;
  for (int k = 0; k < 2000; ++k) cloud.points.emplace_back(u(rng), u(rng), u(rng));
  const KdTree tree(cloud);
  int found = 0, missing = 0;
  for (int q = 0; q < 400; ++q) {
    // Queries inside the cloud and up to 3 m outside it.
    const Eigen::Vector3f query(1.6f * u(rng), 1.6f * u(rng), 1.6f * u(rng));
    float best = std::numeric_limits<float>::infinity();
    std::uint32_t best_index = 0;
    for (std::uint32_t k = 0; k < cloud.points.size(); ++k) {
      const float d = (cloud.points[k] - query).squaredNorm();
      if (d < best) best = d, best_index = k;
    }
    // The tree's own squared distance (its summation order, the last bits can differ from
    // squaredNorm()) as the exact bound: a point at the bound counts.
    std::uint32_t nearest_index = 0;
    float nearest_sq = 0.0f;
    ASSERT_TRUE(tree.nearest(query, &nearest_index, &nearest_sq));
    ASSERT_EQ(nearest_index, best_index);
    for (const float bound : {0.01f, 0.25f, 1.0f, nearest_sq}) {
      std::uint32_t index = 0;
      float sq = -1.0f;
      const bool hit = tree.nearest_within(query, bound, &index, &sq);
      ASSERT_EQ(hit, nearest_sq <= bound) << "query " << q << " bound " << bound;
      if (!hit) {
        ++missing;
        continue;
      }
      ++found;
      EXPECT_EQ(index, best_index);
      EXPECT_EQ(sq, nearest_sq);
      EXPECT_FLOAT_EQ(sq, best);
    }
  }
  EXPECT_GT(found, 400);  // both outcomes were exercised
  EXPECT_GT(missing, 100);
  std::uint32_t index = 0;
  float sq = 0.0f;
  EXPECT_FALSE(tree.nearest_within(Eigen::Vector3f::Zero(), -1.0f, &index, &sq));
  const PointCloud empty;
  EXPECT_FALSE(KdTree(empty).nearest_within(Eigen::Vector3f::Zero(), 1.0f, &index, &sq));
}

}  // namespace
TEST(KdTreeTest, EveryCloudSizeAndManyPointsAtOnePosition) {
  std::mt19937 rng(29);
  std::uniform_real_distribution<float> u(-2.0f, 2.0f);
  // Sizes around the leaf and vector widths, and far more points at one position than a leaf
  // holds (they cannot be told apart by a split plane).
  for (const int n : {1, 2, 7, 8, 9, 55, 56, 57, 113, 300}) {
    PointCloud cloud;
    for (int k = 0; k < n; ++k) cloud.points.emplace_back(u(rng), u(rng), u(rng));
    if (n == 300)
      for (int k = 0; k < 200; ++k) cloud.points.emplace_back(0.5f, 0.5f, 0.5f);
    const KdTree tree(cloud);
    for (int q = 0; q < 50; ++q) {
      const Eigen::Vector3f query =
          q == 0 ? Eigen::Vector3f(0.5f, 0.5f, 0.5f) : Eigen::Vector3f(u(rng), u(rng), u(rng));
      float best = std::numeric_limits<float>::infinity();
      for (const auto& p : cloud.points) {
        const Eigen::Vector3f d = p - query;
        best = std::min(best, d.x() * d.x() + d.y() * d.y() + d.z() * d.z());
      }
      std::uint32_t index = 0;
      float sq = -1.0f;
      ASSERT_TRUE(tree.nearest_within(query, 100.0f, &index, &sq)) << "n " << n;
      EXPECT_EQ(sq, best) << "n " << n << " query " << q;
      const Eigen::Vector3f d = cloud.points[index] - query;
      EXPECT_EQ(sq, d.x() * d.x() + d.y() * d.y() + d.z() * d.z());
      EXPECT_EQ(tree.nearest_within(query, 0.5f * best, &index, &sq), best == 0.0f);
    }
  }
  // 250 points at one position: the 240 nearest of a query there are all at distance 0.
  PointCloud repeated;
  for (int k = 0; k < 250; ++k) repeated.points.emplace_back(1.0f, 2.0f, 3.0f);
  repeated.points.emplace_back(1.0f, 2.0f, 4.0f);
  const KdTree tree(repeated);
  std::vector<std::uint32_t> indices(240);
  std::vector<float> distances(240);
  ASSERT_EQ(tree.knn(Eigen::Vector3f(1.0f, 2.0f, 3.0f), 240, indices.data(), distances.data()),
            240);
  std::sort(indices.begin(), indices.end());
  EXPECT_EQ(std::unique(indices.begin(), indices.end()), indices.end());  // distinct points
  EXPECT_LT(indices.back(), 250u);
  for (const float distance : distances) EXPECT_EQ(distance, 0.0f);
}

TEST(KdTreeTest, RunsOfQueriesFindWhatSingleQueriesFind) {
  std::mt19937 rng(31);
  std::uniform_real_distribution<float> u(-5.0f, 5.0f);
  std::normal_distribution<float> step(0.0f, 0.05f);
  PointCloud cloud;
  // A surface-like scan: a plane, a wall and a post, with repeated points.
  for (int k = 0; k < 3000; ++k) cloud.points.emplace_back(u(rng), u(rng), 0.0f);
  for (int k = 0; k < 1500; ++k) cloud.points.emplace_back(u(rng), 3.0f, 0.5f * (u(rng) + 5.0f));
  for (int k = 0; k < 100; ++k) cloud.points.emplace_back(1.0f, 1.0f, 0.4f);
  const KdTree tree(cloud);
  // A walk that drifts through the cloud (each search starts where the one before ended), with
  // jumps far outside it and back.
  std::vector<Eigen::Vector3f> queries;
  Eigen::Vector3f at(0.0f, 0.0f, 0.2f);
  for (int k = 0; k < 3000; ++k) {
    at += Eigen::Vector3f(step(rng), step(rng), 0.2f * step(rng));
    if (k % 97 == 0 || at.cwiseAbs().maxCoeff() > 5.0f)
      at = Eigen::Vector3f(u(rng), u(rng), 0.1f * u(rng));
    queries.push_back(k % 211 == 0 ? Eigen::Vector3f(40.0f, -30.0f, 9.0f) : at);
  }
  queries.emplace_back(1.0f, 1.0f, 0.4f);  // on the repeated points
  for (const float bound : {0.0f, 0.01f, 0.25f, 1.0f, 1e6f}) {
    std::vector<std::uint32_t> indices(queries.size());
    std::vector<float> distances(queries.size());
    tree.nearest_within(queries, bound, indices.data(), distances.data());
    int found = 0;
    for (std::size_t k = 0; k < queries.size(); ++k) {
      std::uint32_t index = 0;
      float sq = 0.0f;
      if (!tree.nearest_within(queries[k], bound, &index, &sq)) {
        EXPECT_EQ(indices[k], KdTree::kNotFound) << "query " << k << " bound " << bound;
        continue;
      }
      ++found;
      ASSERT_NE(indices[k], KdTree::kNotFound) << "query " << k << " bound " << bound;
      EXPECT_EQ(distances[k], sq) << "query " << k << " bound " << bound;
      const Eigen::Vector3f d = cloud.points[indices[k]] - queries[k];
      EXPECT_EQ(distances[k], d.x() * d.x() + d.y() * d.y() + d.z() * d.z());
    }
    if (bound >= 0.25f) {
      EXPECT_GT(found, 2500) << bound;  // and misses: the queries far outside
    }
  }
  std::uint32_t index = 0;
  float distance = 0.0f;
  const Eigen::Vector3f one(0.0f, 0.0f, 0.0f);
  tree.nearest_within(std::span(&one, 1), -1.0f, &index, &distance);
  EXPECT_EQ(index, KdTree::kNotFound);
  const PointCloud empty;
  KdTree(empty).nearest_within(std::span(&one, 1), 1.0f, &index, &distance);
  EXPECT_EQ(index, KdTree::kNotFound);
}

TEST(KdTreeTest, KnnMatchesBruteForce) {
  std::mt19937 rng(23);
  std::uniform_real_distribution<float> u(-5.0f, 5.0f);
  PointCloud cloud;
  // A plane, a line and repeated points: cells that are flat, thin or a single position.
  for (int k = 0; k < 1500; ++k) cloud.points.emplace_back(u(rng), u(rng), 0.0f);
  for (int k = 0; k < 300; ++k) cloud.points.emplace_back(u(rng), 2.0f, 1.0f);
  for (int k = 0; k < 60; ++k) cloud.points.emplace_back(1.0f, 1.0f, 1.0f);
  const KdTree tree(cloud);
  for (const int k : {1, 10, 25}) {
    for (int q = 0; q < 300; ++q) {
      const Eigen::Vector3f query(u(rng), u(rng), 0.3f * u(rng));
      std::vector<float> brute;
      for (const auto& p : cloud.points) {
        const Eigen::Vector3f d = p - query;
        brute.push_back(d.x() * d.x() + d.y() * d.y() + d.z() * d.z());
      }
      std::sort(brute.begin(), brute.end());
      std::vector<std::uint32_t> indices(static_cast<std::size_t>(k));
      std::vector<float> distances(static_cast<std::size_t>(k));
      ASSERT_EQ(tree.knn(query, k, indices.data(), distances.data()), k);
      for (int n = 0; n < k; ++n) {
        const auto i = static_cast<std::size_t>(n);
        EXPECT_EQ(distances[i], brute[i]) << "k " << k << " query " << q << " neighbour " << n;
        const Eigen::Vector3f d = cloud.points[indices[i]] - query;
        EXPECT_EQ(distances[i], d.x() * d.x() + d.y() * d.y() + d.z() * d.z());
      }
    }
  }
  // More neighbours asked for than points: all of them, nearest first.
  PointCloud small;
  small.points = {{0, 0, 0}, {3, 0, 0}, {1, 0, 0}};
  const KdTree small_tree(small);
  std::uint32_t indices[5];
  float distances[5];
  ASSERT_EQ(small_tree.knn(Eigen::Vector3f::Zero(), 5, indices, distances), 3);
  EXPECT_EQ(indices[0], 0u);
  EXPECT_EQ(indices[1], 2u);
  EXPECT_EQ(indices[2], 1u);
}

TEST(KdTreeTest, RunsOfKnnQueriesFindWhatSingleQueriesFindTiesIncluded) {
  // A grid (many neighbours tied at one distance, where the order points are met decides), a
  // plane with repeated points, queries on the cloud's own points in order (as the covariance
  // estimate asks) with jumps, a NaN and a far query among them.
  PointCloud cloud;
  for (int x = 0; x < 20; ++x)
    for (int y = 0; y < 20; ++y)
      for (int z = 0; z < 3; ++z)
        cloud.points.emplace_back(0.25f * static_cast<float>(x), 0.25f * static_cast<float>(y),
                                  0.25f * static_cast<float>(z));
  std::mt19937 rng(37);
  std::uniform_real_distribution<float> u(-2.0f, 7.0f);
  for (int k = 0; k < 800; ++k) cloud.points.emplace_back(u(rng), u(rng), -1.0f);
  for (int k = 0; k < 40; ++k) cloud.points.emplace_back(2.0f, 2.0f, -1.0f);
  const KdTree tree(cloud);
  std::vector<Eigen::Vector3f> queries = cloud.points;
  queries[100] = Eigen::Vector3f(std::nanf(""), 0.0f, 0.0f);
  queries[101] = Eigen::Vector3f(500.0f, -300.0f, 20.0f);
  for (int k = 0; k < 300; ++k) queries.emplace_back(u(rng), u(rng), 0.2f * u(rng));
  for (const int k : {1, 10, 45}) {
    const auto slots = static_cast<std::size_t>(k);
    std::vector<std::uint32_t> indices(queries.size() * slots);
    std::vector<float> distances(queries.size() * slots);
    std::vector<int> found(queries.size());
    tree.knn(queries, k, indices.data(), distances.data(), found.data());
    for (std::size_t q = 0; q < queries.size(); ++q) {
      std::vector<std::uint32_t> one_indices(slots);
      std::vector<float> one_distances(slots);
      const int one = tree.knn(queries[q], k, one_indices.data(), one_distances.data());
      ASSERT_EQ(found[q], one) << "k " << k << " query " << q;
      for (std::size_t n = 0; n < static_cast<std::size_t>(one); ++n) {
        ASSERT_EQ(indices[q * slots + n], one_indices[n]) << "k " << k << " query " << q;
        ASSERT_EQ(distances[q * slots + n], one_distances[n]) << "k " << k << " query " << q;
      }
    }
    EXPECT_EQ(found[100], 0);  // NaN: nothing is closer
    EXPECT_EQ(found[101], k);
  }
  // More neighbours than points, and an empty tree.
  PointCloud small;
  small.points = {{0, 0, 0}, {3, 0, 0}, {1, 0, 0}};
  const std::vector<Eigen::Vector3f> two = {{0, 0, 0}, {2, 0, 0}};
  std::uint32_t indices[10];
  float distances[10];
  int found[2];
  KdTree(small).knn(two, 5, indices, distances, found);
  EXPECT_EQ(found[0], 3);
  EXPECT_EQ(found[1], 3);
  EXPECT_EQ(distances[5], 1.0f);  // the second query's: (1, 0, 0) and (3, 0, 0), then (0, 0, 0)
  EXPECT_EQ(distances[6], 1.0f);
  EXPECT_EQ(indices[7], 0u);
  EXPECT_EQ(distances[7], 4.0f);
  const PointCloud empty;
  KdTree(empty).knn(two, 5, indices, distances, found);
  EXPECT_EQ(found[0], 0);
  EXPECT_EQ(found[1], 0);
}

}  // namespace carat
