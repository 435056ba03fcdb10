// Pose perturbation: every pose but the first moves by exactly the asked distance and angle.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/registration/pose_perturbation.hpp"

namespace carat {
namespace {

/// Eight poses of a vehicle along a gentle curve (metres, radians).
std::vector<Eigen::Isometry3d> drive() {
  std::vector<Eigen::Isometry3d> T_world_frame;
  for (int k = 0; k < 8; ++k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(0.1 * k, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    T.translation() = Eigen::Vector3d(2.0 * k, 0.3 * k * k, 0.05 * k);
    T_world_frame.push_back(T);
  }
  return T_world_frame;
}

TEST(PosePerturbationTest, ExactMagnitudesAndTheGaugeStays) {
  const std::vector<Eigen::Isometry3d> truth = drive();
  const auto moved = perturb_poses(truth, 0.3, 3.0, 5);
  ASSERT_EQ(moved.size(), truth.size());
  EXPECT_TRUE(moved[0].isApprox(truth[0], 0.0));
  for (std::size_t k = 1; k < moved.size(); ++k) {
    const Eigen::Isometry3d delta = truth[k].inverse() * moved[k];
    EXPECT_NEAR(delta.translation().norm(), 0.3, 1e-9);
    EXPECT_NEAR(Eigen::AngleAxisd(delta.linear()).angle() * 180.0 / M_PI, 3.0, 1e-9);
  }
  EXPECT_THROW(perturb_poses(truth, -1.0, 0.0, 1), Error);
}

}  // namespace
}  // namespace carat
