// BAL bundle adjustment: the Snavely reprojection block (analytic Jacobian against numeric and
// automatic differentiation, the block contract), the BAL reader on real files and on every kind
// of malformed input, the exact write/read round trip, and the cost of a BAL problem directly and
// through a carat Problem.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <cstring>
#include <fstream>
#include <random>
#include <sstream>
#include <thread>

#include "carat/residuals/bal_camera_manifold.hpp"
#include "carat/residuals/bal_problem.hpp"
#include "carat/residuals/io/bal_io.hpp"
#include "carat/residuals/snavely_block.hpp"
#include "carat/residuals/snavely_camera.hpp"
#include "carat/solver/autodiff_block.hpp"
#include "carat/solver/block_checker.hpp"
#include "carat/solver/jacobian_checker.hpp"
#include "test_support.hpp"

namespace carat {
namespace {

/// The BAL reprojection error written once for automatic differentiation.
struct SnavelyFunctor {
  template <typename T>
  bool operator()(const Eigen::Vector2d& observed, const T* camera, const T* point,
                  T* residual) const {
    T image[2];
    snavely_project(camera, point, image);
    residual[0] = image[0] - T(observed.x());
    residual[1] = image[1] - T(observed.y());
    return true;
  }
};

/// A camera 10 m from the origin with rotation vector `w`, looking at points near the origin.
BalCamera test_camera(const Eigen::Vector3d& w) {
  BalCamera camera;
  camera << w, 0.3, -0.2, -10.0, 520.0, -0.04, 0.003;
  return camera;
}

struct BlockCase {
  const char* name;
  Eigen::Vector3d w;
};

class SnavelyBlockTest : public ::testing::TestWithParam<BlockCase> {};

TEST_P(SnavelyBlockTest, JacobianMatchesNumericAndAutomaticDifferentiation) {
  const BalCamera camera = test_camera(GetParam().w);
  const Eigen::Vector3d point(0.7, -1.1, 0.4);
  const SnavelyReprojectionBlock block(12.5, -40.25);
  const double* params[2] = {camera.data(), point.data()};
  const auto camera_manifold = euclidean_manifold(9), point_manifold = euclidean_manifold(3);
  const Manifold* manifolds[2] = {camera_manifold.get(), point_manifold.get()};

  const JacobianCheckResult numeric = check_jacobians(block, manifolds, params);
  EXPECT_TRUE(numeric.ok) << numeric.message;

  BlockCheckOptions options;
  options.jacobian.relative_tolerance = 1e-6;
  const BlockCheckReport contract = check_residual_block(block, manifolds, params, options);
  EXPECT_TRUE(contract.ok) << contract.summary();

  const auto autodiff = make_autodiff_block<2, VariableSize<9>, VariableSize<3>>(
      SnavelyFunctor{}, std::vector<Eigen::Vector2d>{{12.5, -40.25}});
  Eigen::VectorXd r_analytic, r_autodiff;
  Eigen::MatrixXd J_analytic, J_autodiff;
  evaluate_full_jacobian(block, params, &r_analytic, &J_analytic);
  evaluate_full_jacobian(*autodiff, params, &r_autodiff, &J_autodiff);
  EXPECT_LE((r_analytic - r_autodiff).cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_LE((J_analytic - J_autodiff).cwiseAbs().maxCoeff(),
            1e-11 * J_autodiff.cwiseAbs().maxCoeff())
      << "analytic\n"
      << J_analytic << "\nautodiff\n"
      << J_autodiff;
}

TEST_P(SnavelyBlockTest, AboutCentreJacobianIsTheParametersOneThroughTheManifold) {
  const BalCamera camera = test_camera(GetParam().w);
  const Eigen::Vector3d point(0.7, -1.1, 0.4);
  const SnavelyReprojectionBlock parameters(12.5, -40.25);
  const SnavelyReprojectionBlock about_centre(12.5, -40.25, BalCameraTangent::kAboutCentre);
  EXPECT_EQ(about_centre.camera_tangent(), BalCameraTangent::kAboutCentre);
  const double* params[2] = {camera.data(), point.data()};
  const auto camera_manifold = bal_camera_manifold(), point_manifold = euclidean_manifold(3);
  const Manifold* manifolds[2] = {camera_manifold.get(), point_manifold.get()};
  const JacobianCheckResult numeric = check_jacobians(about_centre, manifolds, params);
  EXPECT_TRUE(numeric.ok) << numeric.message;
  // The same rows; the camera columns are the parameters' ones times d(x [+] d)/dd.
  SnavelyReprojectionBlock::Jacobian J_parameters, J_centre;
  const Eigen::Vector2d r_parameters =
      parameters.evaluate(camera.data(), point.data(), &J_parameters);
  const Eigen::Vector2d r_centre = about_centre.evaluate(camera.data(), point.data(), &J_centre);
  EXPECT_EQ(r_parameters, r_centre);
  Eigen::Matrix<double, 9, 9, Eigen::RowMajor> plus_jacobian;
  camera_manifold->plus_jacobian(camera.data(), plus_jacobian.data());
  const Eigen::Matrix<double, 2, 9> chained = J_parameters.leftCols<9>() * plus_jacobian;
  EXPECT_LE((J_centre.leftCols<9>() - chained).cwiseAbs().maxCoeff(),
            1e-12 * chained.cwiseAbs().maxCoeff());
  EXPECT_EQ(J_centre.rightCols<3>(), J_parameters.rightCols<3>());
}

INSTANTIATE_TEST_SUITE_P(
    Rotations, SnavelyBlockTest,
    ::testing::Values(BlockCase{"Identity", Eigen::Vector3d::Zero()},
                      BlockCase{"Tiny", Eigen::Vector3d(2e-5, -1e-5, 3e-5)},
                      BlockCase{"NearSeriesBoundary", Eigen::Vector3d(6e-4, -7e-4, 4e-4)},
                      BlockCase{"Moderate", Eigen::Vector3d(0.3, -0.5, 0.2)},
                      BlockCase{"NearPi", Eigen::Vector3d(1.8, 2.0, -1.4)}),
    [](const ::testing::TestParamInfo<BlockCase>& param_info) { return param_info.param.name; });

TEST(BalCameraManifoldTest, StepsAboutTheCentreAndInvertsItsSteps) {
  const BalCameraManifold manifold;
  EXPECT_STREQ(manifold.name(), "bal_camera");
  const BalCamera x = test_camera({0.3, -0.5, 0.2});
  const auto centre = [](const BalCamera& camera) {
    const Eigen::Vector3d w = camera.head<3>();
    const double angle = w.norm();
    const Eigen::Matrix3d R = Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
    return Eigen::Vector3d(-R.transpose() * camera.segment<3>(3));
  };
  BalCamera y;
  Eigen::Matrix<double, 9, 1> delta;
  delta << 0.02, -0.01, 0.03, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0;
  manifold.plus(x.data(), delta.data(), y.data());  // a rotation alone: the centre stays
  EXPECT_LE((centre(y) - centre(x)).norm(), 1e-13);
  EXPECT_LE((y.head<3>() - x.head<3>() - delta.head<3>()).norm(), 1e-15);
  delta << 0.02, -0.01, 0.03, 0.4, -0.2, 0.1, 3.0, 0.01, -0.002;
  manifold.plus(x.data(), delta.data(), y.data());
  EXPECT_LE((centre(y) - centre(x) - delta.segment<3>(3)).norm(), 1e-13);
  EXPECT_LE((y.tail<3>() - x.tail<3>() - delta.tail<3>()).norm(), 1e-13);
  Eigen::Matrix<double, 9, 1> back;
  manifold.minus(y.data(), x.data(), back.data());
  EXPECT_LE((back - delta).cwiseAbs().maxCoeff(), 1e-13);
  manifold.plus(x.data(), Eigen::Matrix<double, 9, 1>::Zero().eval().data(), y.data());
  EXPECT_LE((y - x).cwiseAbs().maxCoeff(), 1e-14);
  // plus_jacobian against central differences of plus().
  Eigen::Matrix<double, 9, 9, Eigen::RowMajor> analytic, numeric;
  manifold.plus_jacobian(x.data(), analytic.data());
  for (int k = 0; k < 9; ++k) {
    const double h = 1e-6;
    Eigen::Matrix<double, 9, 1> step = Eigen::Matrix<double, 9, 1>::Zero();
    BalCamera plus, minus;
    step[k] = h;
    manifold.plus(x.data(), step.data(), plus.data());
    step[k] = -h;
    manifold.plus(x.data(), step.data(), minus.data());
    numeric.col(k) = (plus - minus) / (2.0 * h);
  }
  EXPECT_LE((analytic - numeric).cwiseAbs().maxCoeff(), 1e-7) << analytic << "\n\n" << numeric;
  EXPECT_TRUE(manifold.is_valid(x.data()));
  BalCamera bad = x;
  bad[4] = std::nan("");
  EXPECT_FALSE(manifold.is_valid(bad.data()));
}

TEST(SnavelyBlockTest, AccumulateIsTheGramOfTheRowsAndRowsAreHonoured) {
  const BalCamera camera = test_camera({0.1, 0.2, -0.3});
  const Eigen::Vector3d point(-0.5, 0.25, 1.0);
  const SnavelyReprojectionBlock block(-3.0, 7.0);
  const double* params[2] = {camera.data(), point.data()};
  SnavelyReprojectionBlock::Jacobian J;
  const Eigen::Vector2d r = block.evaluate(camera.data(), point.data(), &J);
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(12, 12);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(12);
  const double c = block.accumulate(params, H, b);
  EXPECT_NEAR(c, r.squaredNorm(), 1e-12 * c);
  EXPECT_LE((H - J.transpose() * J).cwiseAbs().maxCoeff(), 1e-12 * H.cwiseAbs().maxCoeff());
  EXPECT_LE((b - J.transpose() * r).cwiseAbs().maxCoeff(), 1e-12 * b.cwiseAbs().maxCoeff());
  EXPECT_DOUBLE_EQ(block.squared_norm(params), r.squaredNorm());

  // Rows in any order with repeats; nothing written past them.
  const int rows[3] = {1, 0, 1};
  double residuals[4] = {0, 0, 0, -7.0};
  double jacobian[3 * 12 + 1];
  jacobian[36] = -7.0;
  block.evaluate_rows(params, rows, residuals, jacobian);
  EXPECT_EQ(residuals[0], r[1]);
  EXPECT_EQ(residuals[1], r[0]);
  EXPECT_EQ(residuals[2], r[1]);
  EXPECT_EQ(residuals[3], -7.0);
  EXPECT_EQ(jacobian[36], -7.0);
  for (int col = 0; col < 12; ++col) {
    EXPECT_EQ(jacobian[col], J(1, col));
    EXPECT_EQ(jacobian[12 + col], J(0, col));
  }
}

TEST(SnavelyBlockTest, ResidualIsTheProjectionMinusTheObservation) {
  // w = 0, t = (0, 0, -10), f = 100, k1 = 0.1, k2 = 0.01: X = (1, 2, 0) -> P = (1, 2, -10),
  // p = (0.1, 0.2), r2 = 0.05, d = 1 + 0.005 + 0.000025.
  BalCamera camera;
  camera << 0, 0, 0, 0, 0, -10, 100, 0.1, 0.01;
  const Eigen::Vector3d point(1, 2, 0);
  const double d = 1.0 + 0.1 * 0.05 + 0.01 * 0.05 * 0.05;
  const SnavelyReprojectionBlock block(1.0, -1.0);
  const Eigen::Vector2d r = block.evaluate(camera.data(), point.data(), nullptr);
  EXPECT_NEAR(r.x(), 100 * d * 0.1 - 1.0, 1e-12);
  EXPECT_NEAR(r.y(), 100 * d * 0.2 + 1.0, 1e-12);
  EXPECT_TRUE(in_front_of_camera(camera.data(), point.data()));
  EXPECT_EQ(test::error_of([] { SnavelyReprojectionBlock(std::nan(""), 1.0); }),
            "SnavelyReprojectionBlock: observation (nan, 1) is not finite");
}

TEST(SnavelyBlockTest, ACameraChangedInPlaceIsEvaluatedAtItsNewValues) {
  // The block keeps each thread's last rotations per camera address; a camera whose values
  // change in place (as a solver's buffer does between iterations) must be evaluated afresh.
  const SnavelyReprojectionBlock block(3.0, -2.0, BalCameraTangent::kAboutCentre);
  const Eigen::Vector3d point(0.4, -0.3, 1.2);
  BalCamera in_place = test_camera({0.01, -0.02, 0.03});
  SnavelyReprojectionBlock::Jacobian J_before, J_after, J_fresh;
  const Eigen::Vector2d before = block.evaluate(in_place.data(), point.data(), &J_before);
  for (int k = 0; k < 3; ++k) {  // each angle-axis coordinate alone, by one ulp and by a lot
    for (const double changed : {std::nextafter(in_place[k], 1.0), in_place[k] + 0.3}) {
      const double kept = in_place[k];
      in_place[k] = changed;
      const BalCamera elsewhere = in_place;  // the same values at another address
      const Eigen::Vector2d after = block.evaluate(in_place.data(), point.data(), &J_after);
      const Eigen::Vector2d fresh = block.evaluate(elsewhere.data(), point.data(), &J_fresh);
      EXPECT_EQ(after, fresh) << "coordinate " << k;
      EXPECT_EQ(J_after, J_fresh) << "coordinate " << k;
      EXPECT_EQ(block.squared_norm(std::array<const double*, 2>{in_place.data(), point.data()}),
                fresh.squaredNorm());
      in_place[k] = kept;
    }
  }
  EXPECT_EQ(block.evaluate(in_place.data(), point.data(), nullptr), before);
}

/// A small valid problem: 2 cameras, 2 points, 3 observations.
BalProblem small_problem() {
  BalProblem p;
  p.cameras = {test_camera({0.01, -0.02, 0.03}), test_camera({-0.1, 0.05, 0.2})};
  p.points = {Eigen::Vector3d(0.5, -0.25, 1.0), Eigen::Vector3d(-1.0, 0.75, -0.5)};
  p.observations = {{0, 0, 1.5, -2.5}, {1, 0, 3.0, 4.0}, {1, 1, -1.0, 2.0}};
  return p;
}

std::string to_text(const BalProblem& problem) {
  std::ostringstream out;
  write_bal(out, problem);
  return out.str();
}

TEST(BalIoTest, ReadsTheDubrovnikSubsets) {
  for (const auto& [file, observations] :
       {std::pair<std::string, std::size_t>{"dubrovnik-3-7-pre.txt", 19},
        std::pair<std::string, std::size_t>{"dubrovnik-3-7-18-pre.txt", 18}}) {
    if (!test::has_data("posegraph/" + file)) GTEST_SKIP() << "no " << file << " in the data";
    const BalProblem bal = read_bal(test::data_dir() / "posegraph" / file);
    EXPECT_EQ(bal.cameras.size(), 3u);
    EXPECT_EQ(bal.points.size(), 7u);
    ASSERT_EQ(bal.observations.size(), observations);
    EXPECT_EQ(bal.observations[0].camera, 0);
    EXPECT_EQ(bal.observations[0].point, 0);
    EXPECT_EQ(bal.observations[0].x, -3.859900e+02);
    EXPECT_EQ(bal.observations[0].y, 3.871200e+02);
    EXPECT_EQ(bal.cameras[0][0], -1.6943983532198115e-02);
    EXPECT_EQ(bal.cameras[0][6], 1.4300319432711681e+03);
    EXPECT_EQ(bal.points[6].z(), -5.2070299568846060e+01);
    EXPECT_EQ(count_points_behind_cameras(bal), 0u);
    // The direct cost and the carat Problem's agree.
    Problem problem;
    const BalVariables variables = add_bal_problem(bal, &problem);
    EXPECT_EQ(problem.num_residual_blocks(), static_cast<int>(observations));
    EXPECT_TRUE(problem.is_eliminable(variables.points[3]));
    EXPECT_FALSE(problem.is_eliminable(variables.cameras[1]));
    const double cost = bal_cost(bal);
    EXPECT_GT(cost, 0.0);
    EXPECT_NEAR(problem.evaluate_cost(), cost, 1e-12 * cost);
  }
}

TEST(BalIoTest, WriteThenReadIsBitExact) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  BalProblem p = small_problem();
  // Values that need all 17 digits, tiny and huge magnitudes, negative zero, subnormals.
  p.cameras[0] << 0.1 + 0.2, -1.0 / 3.0, 2.0 / 3.0, u(rng), u(rng), -10.0, 1234.5678901234567,
      -5e-320, 1e300;
  p.cameras[1][7] = -0.0;
  p.points[1] << std::nextafter(1.0, 2.0), u(rng) * 1e-12, u(rng) * 1e12;
  p.observations[2].x = std::nextafter(-1.0, 0.0);
  const auto dir = test::scratch_dir("bal_round_trip");
  write_bal(dir / "p.txt", p);
  const BalProblem q = read_bal(dir / "p.txt");
  ASSERT_EQ(q.cameras.size(), p.cameras.size());
  ASSERT_EQ(q.points.size(), p.points.size());
  ASSERT_EQ(q.observations.size(), p.observations.size());
  for (std::size_t i = 0; i < p.cameras.size(); ++i) {
    EXPECT_EQ(std::memcmp(p.cameras[i].data(), q.cameras[i].data(), 9 * sizeof(double)), 0) << i;
  }
  for (std::size_t i = 0; i < p.points.size(); ++i) {
    EXPECT_EQ(std::memcmp(p.points[i].data(), q.points[i].data(), 3 * sizeof(double)), 0) << i;
  }
  for (std::size_t k = 0; k < p.observations.size(); ++k) {
    EXPECT_EQ(q.observations[k].camera, p.observations[k].camera);
    EXPECT_EQ(q.observations[k].point, p.observations[k].point);
    EXPECT_EQ(std::memcmp(&q.observations[k].x, &p.observations[k].x, sizeof(double)), 0);
    EXPECT_EQ(std::memcmp(&q.observations[k].y, &p.observations[k].y, sizeof(double)), 0);
  }
  EXPECT_EQ(to_text(q), to_text(p));
  EXPECT_TRUE(std::signbit(q.cameras[1][7]));
}

TEST(BalIoTest, ReadsAnyWhitespaceLayout) {
  const BalProblem p = parse_bal(
      "2 2 3 0 0 1.5 -2.5\t1 0 3 4\r\n1 1 -1 2 1 2 3 4 5 -6 7 8 9 9 8 7 6 5 -4 3 2 1\n\n1 2 -3 4 5 "
      "6",
      "inline");
  ASSERT_EQ(p.observations.size(), 3u);
  EXPECT_EQ(p.observations[1].x, 3.0);
  EXPECT_EQ(p.cameras[1][8], 1.0);
  EXPECT_EQ(p.points[1].z(), 6.0);
}

struct MalformedCase {
  const char* name;
  std::string text;
  std::string message;
};

class BalMalformedTest : public ::testing::TestWithParam<MalformedCase> {};

TEST_P(BalMalformedTest, ThrowsOneLineNamingFileLineAndProblem) {
  EXPECT_EQ(test::error_of([] { (void)parse_bal(GetParam().text, "t.bal"); }), GetParam().message);
}

const std::string kCameras = "1 2 3 4 5 -6 7 8 9\n9 8 7 6 5 -4 3 2 1\n";  // lines 5-6 below
const std::string kObservations = "0 0 1.5 -2.5\n1 0 3 4\n1 1 -1 2\n";    // lines 2-4
const std::string kValid = "2 2 3\n" + kObservations + kCameras + "1 2 -3\n4 5 6\n";

/// kValid with the first `from` replaced by `to`.
std::string valid_with(const std::string& from, const std::string& to) {
  std::string text = kValid;
  text.replace(text.find(from), from.size(), to);
  return text;
}

INSTANTIATE_TEST_SUITE_P(
    EveryProblem, BalMalformedTest,
    ::testing::Values(
        MalformedCase{"Empty", "", "t.bal:1: the file ends in the header (truncated?)"},
        MalformedCase{"NegativeCount", "2 2 -3\n",
                      "t.bal:1: header: num_observations must be an integer in [1, 2147483647], "
                      "found '-3'"},
        MalformedCase{"OverflowingCount", "2 99999999999999999999 3\n",
                      "t.bal:1: header: num_points must be an integer in [1, 2147483647], found "
                      "'99999999999999999999'"},
        MalformedCase{"ZeroCount", "0 2 3\n",
                      "t.bal:1: header: num_cameras must be an integer in [1, 2147483647], found "
                      "'0'"},
        MalformedCase{"CountsBeyondTheFileSize", "1000 1000 1000000\n0 0 1 2\n",
                      "t.bal:1: header: 1000 cameras, 1000 points and 1000000 observations need "
                      "4012000 numbers (at least 8023999 bytes), but only 8 bytes follow: the "
                      "file is truncated"},
        MalformedCase{"Truncated", "2 2 3\n" + kObservations + kCameras + "1 2 -3\n4 5\n",
                      "t.bal:8: the file ends in point 1 (coordinate 3 of 3; the header promises "
                      "2 points) (truncated?)"},
        MalformedCase{"TruncatedObservation", "2 2 3\n0 0 1.5 -2.5\n1 0 3 4\n1 1 -1",
                      "t.bal:1: header: 2 cameras, 2 points and 3 observations need 36 numbers "
                      "(at least 71 bytes), but only 27 bytes follow: the file is truncated"},
        MalformedCase{"TruncatedAfterLongNumbers",
                      "1 1 2\n0 0 1.00000000000000000000 2.00000000000000000000\n0 0 "
                      "3.00000000000000000000 4.00000000000000000000\n1 2 3 4 5 6 7 8 9\n1",
                      "t.bal:5: the file ends in point 0 (coordinate 2 of 3; the header promises "
                      "1 points) (truncated?)"},
        MalformedCase{"NotFinite", valid_with("1.5", "nan"),
                      "t.bal:2: observation x 'nan' is not finite"},
        MalformedCase{"OutOfRange", valid_with("-2.5", "-1e999"),
                      "t.bal:2: observation y '-1e999' is out of range"},
        MalformedCase{"NotANumber", valid_with("1.5", "1.5x"),
                      "t.bal:2: cannot read observation x from '1.5x'"},
        MalformedCase{"CameraParameterNotFinite", valid_with("1 2 3 4 5", "1 2 3 4 inf"),
                      "t.bal:5: camera 0 parameter 4 'inf' is not finite"},
        MalformedCase{"CameraIndexOutOfRange", valid_with("1 0 3 4", "2 0 3 4"),
                      "t.bal:3: camera index 2 is out of range [0, 2)"},
        MalformedCase{"NegativePointIndex", valid_with("0 0 1.5", "0 -1 1.5"),
                      "t.bal:2: point index -1 is out of range [0, 2)"},
        MalformedCase{"FractionalIndex", valid_with("0 0 1.5", "0.5 0 1.5"),
                      "t.bal:2: cannot read a camera index from '0.5'"},
        MalformedCase{"TrailingData", "2 2 3\n" + kObservations + kCameras + "1 2 -3\n4 5 6\n7\n",
                      "t.bal:9: unexpected data '7' after the last point (the header promises 2 "
                      "points)"},
        MalformedCase{"CameraObservesNothing",
                      "3 2 3\n" + kObservations + kCameras + "1 2 3 4 5 -6 7 8 9\n1 2 -3\n4 5 6\n",
                      "t.bal:7: camera 2 observes no point (every camera and point must take part "
                      "in an observation)"},
        MalformedCase{"PointObservedByNoCamera",
                      "2 3 3\n" + kObservations + kCameras + "1 2 -3\n4 5 6\n7 8 9\n",
                      "t.bal:9: point 2 is observed by no camera (every camera and point must take "
                      "part in an observation)"}),
    [](const ::testing::TestParamInfo<MalformedCase>& param_info) {
      return param_info.param.name;
    });

TEST(BalIoTest, RefusesDirectoriesAndMissingFiles) {
  const auto dir = test::scratch_dir("bal_bad_paths");
  EXPECT_EQ(test::error_of([&] { (void)read_bal(dir); }),
            dir.string() + ": is a directory, not a file");
  EXPECT_EQ(test::error_of([&] { (void)read_bal(dir / "missing.txt"); }),
            (dir / "missing.txt").string() + ": no such file");
  // A problem the reader would refuse is not written either, and the path stays untouched.
  BalProblem p = small_problem();
  p.observations[2].point = 0;  // point 1 unobserved
  EXPECT_EQ(test::error_of([&] { write_bal(dir / "out.txt", p); }),
            "write_bal: point 1 is observed by no camera");
  EXPECT_FALSE(std::filesystem::exists(dir / "out.txt"));
}

/// read_bal() of `text` written into a FIFO by another thread (an input of unknown size).
std::string read_through_fifo(const std::string& text, BalProblem* out) {
  const auto dir = test::scratch_dir("bal_fifo");
  const auto fifo = dir / "in.bal";
  if (mkfifo(fifo.c_str(), 0600) != 0) return "(no fifo)";
  std::thread writer([&] { std::ofstream(fifo) << text; });
  std::string message = test::error_of([&] { *out = read_bal(fifo); });
  writer.join();
  return message;
}

TEST(BalIoTest, ReadsAStreamOfUnknownSize) {
  BalProblem p;
  EXPECT_EQ(read_through_fifo(kValid, &p), "(no error)");
  EXPECT_EQ(p.cameras.size(), 2u);
  EXPECT_EQ(p.points[1].z(), 6.0);
  const std::string fifo = (test::scratch_dir("bal_fifo") / "in.bal").string();
  EXPECT_EQ(read_through_fifo(valid_with("1 1 -1 2", "1 0 -1 2"), &p),
            fifo +
                ":8: point 1 is observed by no camera (every camera and point must take part "
                "in an observation)");
  EXPECT_EQ(read_through_fifo("3 2 3\n" + kObservations + kCameras + "1 2 3 4 5 -6 7 8 9\n", &p),
            fifo +
                ":7: camera 2 observes no point (every camera and point must take part in an "
                "observation)");
}

TEST(BalProblemTest, CostDirectAndThroughTheProblemAgreeAndSolvedValuesComeBack) {
  const BalProblem bal = small_problem();
  Problem problem;
  const BalVariables variables = add_bal_problem(bal, &problem);
  ASSERT_EQ(variables.cameras.size(), 2u);
  ASSERT_EQ(variables.points.size(), 2u);
  const double cost = bal_cost(bal);
  EXPECT_NEAR(problem.evaluate_cost(), cost, 1e-12 * cost);

  // Move the variables and read them back.
  problem.mutable_value(variables.cameras[1])[6] = 777.0;
  problem.mutable_value(variables.points[0])[2] = -3.5;
  BalProblem updated = bal;
  update_bal_problem(problem, variables, &updated);
  EXPECT_EQ(updated.cameras[1][6], 777.0);
  EXPECT_EQ(updated.points[0].z(), -3.5);
  EXPECT_EQ(updated.cameras[0], bal.cameras[0]);
  EXPECT_NEAR(problem.evaluate_cost(), bal_cost(updated), 1e-12 * bal_cost(updated));
}

TEST(BalProblemTest, CamerasStepAboutTheirCentreUnlessParametersAreAsked) {
  const BalProblem bal = small_problem();
  for (const BalCameraTangent tangent :
       {BalCameraTangent::kAboutCentre, BalCameraTangent::kParameters}) {
    Problem problem;
    const BalVariables variables = tangent == BalCameraTangent::kAboutCentre
                                       ? add_bal_problem(bal, &problem)
                                       : add_bal_problem(bal, &problem, nullptr, tangent);
    const std::string expected =
        tangent == BalCameraTangent::kAboutCentre ? "bal_camera" : "euclidean";
    for (const VariableId camera : variables.cameras) {
      EXPECT_EQ(problem.manifold(camera).name(), expected);
    }
    EXPECT_EQ(problem.manifold(variables.points[0]).name(), std::string("euclidean"));
    // Every block's Jacobian matches differences through its variables' manifolds.
    const ProblemCheckReport check = check_problem(problem);
    EXPECT_TRUE(check.ok) << check.summary();
  }
}

TEST(BalProblemTest, CountsPointsBehindTheirCameras) {
  BalProblem bal = small_problem();
  EXPECT_EQ(count_points_behind_cameras(bal), 0u);
  bal.points[0].z() = 20.0;  // P_z = 20 - 10 > 0 for both cameras (rotations are small)
  EXPECT_EQ(count_points_behind_cameras(bal), 2u);
  EXPECT_TRUE(std::isfinite(bal_cost(bal)));  // still a residual: documented, not refused

  // The count is in_front_of_camera()'s, observation by observation, for rotations on both sides
  // of the Taylor branch (|w| below and above 1e-3 rad) and points on both sides of the cameras.
  bal.cameras[0].head<3>() << 2e-4, -1e-4, 3e-4;
  bal.cameras[1].head<3>() << 0.9, -1.7, 0.4;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> coordinate(-30.0, 30.0);
  bal.points.resize(40);
  bal.observations.clear();
  for (int i = 0; i < 40; ++i) {
    bal.points[static_cast<std::size_t>(i)] =
        Eigen::Vector3d(coordinate(rng), coordinate(rng), coordinate(rng));
    bal.observations.push_back({i % 2, i, 0.0, 0.0});
    bal.observations.push_back({(i + 1) % 2, i, 0.0, 0.0});
  }
  std::size_t behind = 0;
  for (const BalObservation& o : bal.observations) {
    if (!in_front_of_camera(bal.cameras[static_cast<std::size_t>(o.camera)].data(),
                            bal.points[static_cast<std::size_t>(o.point)].data())) {
      ++behind;
    }
  }
  EXPECT_GT(behind, 10u);
  EXPECT_LT(behind, 70u);
  EXPECT_EQ(count_points_behind_cameras(bal), behind);
}

}  // namespace
}  // namespace carat
