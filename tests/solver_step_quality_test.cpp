// Judging a trial step: the model's predicted decrease (damped and undamped forms), the gain
// ratio, and the rule for steps whose predicted decrease is below the rounding of the cost.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <limits>

#include "../solver/src/step_quality.hpp"

namespace carat {
namespace {

using internal::judge_step;
using internal::StepQuality;

constexpr double kEps = std::numeric_limits<double>::epsilon();

TEST(StepQualityTest, GainRatioIsTheActualOverThePredictedDecrease) {
  const StepQuality step = judge_step(10.0, 8.0, 4.0);
  EXPECT_EQ(step.cost_decrease, 2.0);
  EXPECT_EQ(step.model_decrease, 4.0);
  EXPECT_EQ(step.measured_ratio, 0.5);
  EXPECT_EQ(step.gain_ratio, 0.5);
  EXPECT_FALSE(step.below_rounding);
  EXPECT_TRUE(step.cost_is_finite);
}

TEST(StepQualityTest, NoPredictedDecreaseGivesRatioMinusOne) {
  for (const double predicted : {0.0, -1.0}) {
    const StepQuality step = judge_step(10.0, 9.0, predicted);
    EXPECT_EQ(step.measured_ratio, -1.0) << predicted;
    EXPECT_EQ(step.gain_ratio, -1.0) << predicted;
    EXPECT_FALSE(step.below_rounding) << predicted;
  }
}

TEST(StepQualityTest, CostRoundingIsSixtyFourEpsilonsOfTheCost) {
  EXPECT_EQ(internal::cost_rounding(1.0), 64.0 * kEps);
  EXPECT_EQ(internal::cost_rounding(-2.0), 128.0 * kEps);
  EXPECT_EQ(internal::cost_rounding(0.0), 0.0);
}

TEST(StepQualityTest, AStepBelowTheRoundingCountsAsRatioOne) {
  // Cost 1: rounding 64 eps. The model predicts 10 eps and the cost rises by 32 eps.
  const StepQuality step = judge_step(1.0, 1.0 + 32.0 * kEps, 10.0 * kEps);
  EXPECT_TRUE(step.below_rounding);
  EXPECT_EQ(step.gain_ratio, 1.0);
  EXPECT_DOUBLE_EQ(step.measured_ratio, -3.2);
  EXPECT_EQ(step.cost_decrease, -32.0 * kEps);
}

TEST(StepQualityTest, TheRoundingBoundsAreInclusive) {
  const double rounding = 64.0 * kEps;
  // Predicted decrease exactly at the rounding, cost risen by exactly the rounding: excused.
  EXPECT_TRUE(judge_step(1.0, 1.0 + rounding, rounding).below_rounding);
  // A predicted decrease just above the rounding is measured as it is.
  const StepQuality measured = judge_step(1.0, 1.0, std::nextafter(rounding, 1.0));
  EXPECT_FALSE(measured.below_rounding);
  EXPECT_EQ(measured.gain_ratio, 0.0);
  // A cost rise beyond the rounding is not excused.
  const StepQuality risen = judge_step(1.0, 1.0 + 2.0 * rounding, 10.0 * kEps);
  EXPECT_FALSE(risen.below_rounding);
  EXPECT_LT(risen.gain_ratio, 0.0);
}

TEST(StepQualityTest, NonFiniteTrialCostsAreMarkedAndNeverExcused) {
  for (const double trial :
       {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    const StepQuality step = judge_step(1.0, trial, 10.0 * kEps);
    EXPECT_FALSE(step.cost_is_finite) << trial;
    EXPECT_FALSE(step.below_rounding) << trial;
    EXPECT_FALSE(step.gain_ratio > 0.0) << trial;
  }
}

TEST(StepQualityTest, ModelDecreaseOfAGivenStep) {
  // -g.d - 1/2 d.Hd with g = (2, 1), d = (-1, 0), H = 2 I (Hd = (-2, 0)): 2 - 1 = 1.
  EXPECT_EQ(internal::model_decrease(Eigen::Vector2d(2.0, 1.0), Eigen::Vector2d(-1.0, 0.0),
                                     Eigen::Vector2d(-2.0, 0.0)),
            1.0);
}

TEST(StepQualityTest, DampedFormAgreesWithTheUndampedModelForTheSolvedStep) {
  Eigen::Matrix3d A;
  A << 2.0, -1.0, 0.5, 0.3, 1.5, -0.2, 0.0, 0.4, 3.0;
  const Eigen::Matrix3d H = A.transpose() * A;
  const Eigen::Vector3d gradient(0.7, -1.3, 0.25);
  const Eigen::Vector3d damping(0.1, 2.0, 0.03);
  Eigen::Matrix3d damped = H;
  damped.diagonal() += damping;
  const Eigen::VectorXd delta = damped.ldlt().solve(-gradient);
  const Eigen::VectorXd h_delta = H * delta;
  const double undamped = internal::model_decrease(gradient, delta, h_delta);
  const double from_damping = internal::damped_model_decrease(gradient, delta, damping);
  EXPECT_GT(undamped, 0.0);
  EXPECT_NEAR(from_damping, undamped, 1e-13 * undamped);
}

}  // namespace
}  // namespace carat
