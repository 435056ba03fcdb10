// A frame: its own geometric constraint (planes, corridors, outliers) and too few points.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <memory>
#include <random>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/registration/frame.hpp"

namespace carat {
namespace {

using ::testing::HasSubstr;

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

TEST(FrameTest, TooFewPointsIsAnError) {
  PointCloud cloud;
  for (int k = 0; k < 28; ++k) cloud.points.emplace_back(static_cast<float>(k) * 2.0f, 0.0f, 0.0f);
  EXPECT_THAT([&] { preprocess_frame(cloud, PreprocessOptions{}, "scan.bin"); },
              ::testing::ThrowsMessage<Error>(HasSubstr("scan.bin: only 28 points")));
}

}  // namespace
}  // namespace carat
