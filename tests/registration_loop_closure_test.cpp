// Scan Context and loop closure: the descriptor's yaw, sparse scans, options out of range, and a
// two-lap synthetic drive whose heading drifts by 5 degrees per 100 m, mapped with and without
// the loop step.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <set>
#include <string>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/registration/dense_graph.hpp"
#include "carat/registration/frame.hpp"
#include "carat/registration/frame_store.hpp"
#include "carat/registration/global_registration.hpp"
#include "carat/registration/loop_closure.hpp"
#include "carat/registration/scan_context.hpp"
#include "carat/registration/trajectory_error.hpp"
#include "carat/sim/pipeline.hpp"
#include "carat/sim/sequence.hpp"
#include "carat/sim/world.hpp"

namespace carat {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

PointCloud rotated(const PointCloud& cloud, double yaw) {
  const Eigen::Matrix3f R =
      Eigen::AngleAxisf(static_cast<float>(yaw), Eigen::Vector3f::UnitZ()).toRotationMatrix();
  PointCloud out;
  for (const auto& p : cloud.points) out.points.push_back(R * p);
  return out;
}

PointCloud scan_of_the_world() {
  const SyntheticWorld world;
  SyntheticTrajectoryOptions drive;
  drive.frames = 10;
  drive.laps = 1;
  return world.scan(world.trajectory(drive)[3], 7);
}

TEST(ScanContextTest, TheBestShiftGivesTheYaw) {
  const PointCloud scan = scan_of_the_world();
  const ScanContext a = make_scan_context(scan);
  ASSERT_TRUE(a.valid);
  EXPECT_EQ(a.bins.size(), 20u * 60u);
  EXPECT_EQ(a.ring_key.size(), 20u);
  for (const double yaw_deg : {0.0, 42.0, -120.0, 179.0, -33.0}) {
    // The query sees the candidate's points turned by yaw: p_query = R_z(yaw) p_candidate.
    const ScanContext turned = make_scan_context(rotated(scan, yaw_deg * kDeg));
    const ScanContextMatch match = match_scan_contexts(turned, a);
    EXPECT_LT(match.distance, 0.15) << yaw_deg;
    double error = std::remainder(match.yaw - yaw_deg * kDeg, 2 * std::numbers::pi);
    EXPECT_LE(std::abs(error), 6.0 * kDeg) << yaw_deg << " got " << match.yaw / kDeg;
    // Ring keys barely change with the yaw (only points near sector borders move bins).
    double key_change = 0.0;
    for (int r = 0; r < 20; ++r) key_change += std::abs(turned.ring_key[r] - a.ring_key[r]) / 20;
    EXPECT_LT(key_change, 0.1) << yaw_deg;
  }
  EXPECT_EQ(match_scan_contexts(a, a).distance, 0.0);
  EXPECT_EQ(match_scan_contexts(a, a).shift, 0);
}

TEST(ScanContextTest, SparseScansAndBadOptionsAreReported) {
  PointCloud few;
  for (int k = 0; k < 5; ++k) few.points.emplace_back(static_cast<float>(k + 1), 0.0f, 0.0f);
  const ScanContext sparse = make_scan_context(few);
  EXPECT_FALSE(sparse.valid);
  EXPECT_LE(sparse.occupied_bins, 5);
  const ScanContext empty = make_scan_context(PointCloud{});
  EXPECT_FALSE(empty.valid);
  EXPECT_EQ(match_scan_contexts(empty, empty).distance, 1.0);
  ScanContextOptions options;
  options.sectors = 2;
  try {
    make_scan_context(few, options);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "Scan Context: sectors must be >= 4, got 2");
  }
  options = {};
  options.max_range = -1.0;
  EXPECT_THROW(make_scan_context(few, options), Error);
  ScanContextOptions other;
  other.rings = 10;
  EXPECT_THROW(match_scan_contexts(make_scan_context(few), make_scan_context(few, other)), Error);
}

/// Two laps of 100 frames; the guess turns by 10 degrees per 100 m, so the second lap starts
/// about 9 m away from the first and the scans of one place do not overlap at the guess.
struct DriftingDrive {
  SyntheticPipeline pipeline;
  std::vector<Eigen::Isometry3d> guess;
};

const DriftingDrive& drifting_drive() {
  static const DriftingDrive drive = [] {
    SyntheticPipelineOptions options;
    options.odometry = false;
    options.dense_graph = false;
    options.drift = DriftOptions{
        .seed = 3, .translation_sigma = 0.005, .rotation_sigma_deg = 0.02, .heading_bias_deg = 0.1};
    options.threads = 2;
    DriftingDrive d{simulate_pipeline(options), {}};
    d.guess = d.pipeline.T_world_drift;
    return d;
  }();
  return drive;
}

double ate_rmse(std::span<const Eigen::Isometry3d> estimate,
                std::span<const Eigen::Isometry3d> truth) {
  return compute_ate(estimate, truth).rmse;
}

/// GRE (exact, M = 29) over the dense graph at `initial`; its ATE against the truth, and in
/// *loop_pairs the graph's pairs that join the two laps at one place (frames about 50 apart).
double mapped_ate(const DriftingDrive& d, std::span<const Eigen::Isometry3d> initial,
                  std::size_t* loop_pairs) {
  DenseGraphOptions graph_options;
  graph_options.num_threads = 2;
  FrameStore frames(d.pipeline.frames);
  const auto pairs = build_dense_graph(frames, initial, graph_options);
  *loop_pairs = 0;
  for (const FramePair& p : pairs) *loop_pairs += std::abs(p.source - p.target - 50) <= 5;
  GlobalRegistrationOptions options;
  options.num_threads = 2;
  const auto result = optimize_registration(frames, pairs, initial, options);
  return ate_rmse(result.T_world_frame, d.pipeline.T_world_truth);
}

TEST(LoopClosureTest, ADriftingTwoLapDriveIsClosedAndMapped) {
  const DriftingDrive& d = drifting_drive();
  const auto& truth = d.pipeline.T_world_truth;
  // The drift is as described: the guess's second lap starts far from the first.
  const double start_gap = (d.guess[50].translation() - d.guess[0].translation()).norm();
  EXPECT_GT(start_gap, 5.0);

  LoopClosureOptions options;
  options.num_threads = 2;
  FrameStore frames(d.pipeline.frames);
  const LoopClosureResult closed = close_loops(frames, d.guess, options);
  EXPECT_TRUE(closed.sparse_frames.empty());
  ASSERT_EQ(closed.checks.size(), closed.candidates.size());
  // Every accepted loop measures the true relative pose; most are revisits (the same place on
  // the other lap: frames 50 apart), the rest frames that see the same streets.
  std::size_t revisit_candidates = 0;
  std::size_t revisits_accepted = 0;
  for (const LoopCheck& check : closed.checks) {
    const auto i = static_cast<std::size_t>(check.candidate.pair.target);
    const auto j = static_cast<std::size_t>(check.candidate.pair.source);
    const bool revisit = (truth[i].translation() - truth[j].translation()).norm() < 5.0;
    revisit_candidates += revisit;
    if (check.verdict != LoopVerdict::kAccepted) continue;
    revisits_accepted += revisit;
    const Eigen::Isometry3d error =
        (truth[i].inverse() * truth[j]).inverse() * check.registration.T_target_source;
    EXPECT_LT(error.translation().norm(), 0.2) << i << " - " << j;
    EXPECT_LT(Eigen::AngleAxisd(error.linear()).angle(), 0.5 * kDeg) << i << " - " << j;
  }
  EXPECT_GE(revisit_candidates, 25u);  // the second lap has 50 frames on the first
  EXPECT_GE(revisits_accepted, 20u);
  EXPECT_EQ(closed.odometry.size(), truth.size() - 1);

  // The loop-closed guess, then the dense graph and global registration: ATE below 0.25 m.
  const double guess_ate = ate_rmse(d.guess, truth);
  const double closed_ate = ate_rmse(closed.T_world_frame, truth);
  EXPECT_GT(guess_ate, 2.0);
  EXPECT_LT(closed_ate, 0.5);
  std::size_t loop_pairs = 0;
  EXPECT_LT(mapped_ate(d, closed.T_world_frame, &loop_pairs), 0.25);
  EXPECT_GT(loop_pairs, 100u);
  // Without the loop step the dense graph at the guess misses most loop pairs and the map stays
  // off by metres.
  std::size_t guess_loop_pairs = 0;
  EXPECT_GT(mapped_ate(d, d.guess, &guess_loop_pairs), 1.0);
  EXPECT_LT(guess_loop_pairs, loop_pairs / 4);
}

TEST(LoopClosureTest, ScansOfDifferentPlacesAreNotAccepted) {
  // Half a lap of this city followed by half a lap of another one: no place is seen twice, so
  // every candidate the descriptors propose must fail validation (there is no odometry between
  // the halves, so the stages run on their own).
  const DriftingDrive& d = drifting_drive();
  SyntheticPipelineOptions other;
  other.world.seed = 11;
  other.world.block_size = 60.0;  // other streets: the same seedless layout would look alike
  other.world.street_width = 20.0;
  other.odometry = false;
  other.dense_graph = false;
  other.threads = 2;
  const SyntheticPipeline elsewhere = simulate_pipeline(other);
  std::vector<std::shared_ptr<const Frame>> both(d.pipeline.frames.begin(),
                                                 d.pipeline.frames.begin() + 25);
  both.insert(both.end(), elsewhere.frames.begin(), elsewhere.frames.begin() + 25);
  FrameStore frames(std::move(both));
  std::vector<Eigen::Isometry3d> guess(d.pipeline.T_world_truth.begin(),
                                       d.pipeline.T_world_truth.begin() + 25);
  for (int k = 0; k < 25; ++k) {
    Eigen::Isometry3d far = elsewhere.T_world_truth[static_cast<std::size_t>(k)];
    far.translation().x() += 500.0;
    guess.push_back(far);
  }
  LoopClosureOptions options;
  options.num_threads = 2;
  options.max_descriptor_distance = 1.0;  // let every descriptor match through to GICP
  const auto candidates = find_loop_candidates(frames, guess, options);
  EXPECT_GT(candidates.size(), 5u);
  const auto checks = validate_loop_candidates(frames, guess, candidates, options);
  ASSERT_EQ(checks.size(), candidates.size());
  for (const LoopCheck& check : checks) {
    EXPECT_NE(check.verdict, LoopVerdict::kAccepted)
        << check.candidate.pair.target << " - " << check.candidate.pair.source;
  }
}

TEST(LoopClosureTest, ACorridorOfIdenticalScansIsNotAccepted) {
  // Two walls and a floor along x, seen the same from every pose 5 m apart: every descriptor is
  // the same, so every older frame is a perfect candidate, and GICP cannot fix the position
  // along the corridor: each must be refused as degenerate, none accepted blindly.
  PointCloud corridor;
  for (int i = 0; i < 200; ++i) {
    for (int j = 0; j < 12; ++j) {
      const float x = -50.0f + 0.5f * static_cast<float>(i);
      const float t = 0.25f * static_cast<float>(j);
      corridor.points.emplace_back(x, -3.0f, -1.5f + t);
      corridor.points.emplace_back(x, 3.0f, -1.5f + t);
      corridor.points.emplace_back(x, -2.75f + 0.5f * static_cast<float>(j), -1.8f);
    }
  }
  PreprocessOptions preprocess;
  preprocess.voxel_size = 0.3;
  const auto frame = preprocess_frame(corridor, preprocess, "corridor");
  FrameStore frames(std::vector<std::shared_ptr<const Frame>>(40, frame));
  std::vector<Eigen::Isometry3d> guess(40, Eigen::Isometry3d::Identity());
  for (int k = 0; k < 40; ++k) guess[static_cast<std::size_t>(k)].translation().x() = 5.0 * k;
  LoopClosureOptions options;
  options.num_threads = 2;
  const auto candidates = find_loop_candidates(frames, guess, options);
  EXPECT_EQ(candidates.size(), 20u);  // frames 20..39 have frames 100 m back
  for (const LoopCandidate& c : candidates) EXPECT_EQ(c.descriptor_distance, 0.0);
  const auto checks = validate_loop_candidates(frames, guess, candidates, options);
  for (const LoopCheck& check : checks) EXPECT_EQ(check.verdict, LoopVerdict::kDegenerate);
}

TEST(LoopClosureTest, ALoopFarFromTheGuessIsRejected) {
  // A true revisit (the same place on the two laps), but a guess whose second lap is shifted by
  // 60 m: farther than odometry drifts over the path between the frames (10 % of it), so a loop
  // that would move the second lap there is refused, unless the limit is lifted.
  const DriftingDrive& d = drifting_drive();
  const auto& truth = d.pipeline.T_world_truth;
  FrameStore frames(d.pipeline.frames);
  const int i = 10;
  const int j = 60;
  std::vector<Eigen::Isometry3d> guess(truth.begin(), truth.end());
  for (std::size_t k = 55; k < guess.size(); ++k)
    guess[k].translation() += Eigen::Vector3d(60.0, 0.0, 0.0);
  const Eigen::Isometry3d T_ij =
      truth[static_cast<std::size_t>(i)].inverse() * truth[static_cast<std::size_t>(j)];
  const LoopCandidate candidate{FramePair{i, j, 0.0}, 0.1,
                                std::atan2(T_ij.linear()(1, 0), T_ij.linear()(0, 0))};
  LoopClosureOptions options;
  const auto far = validate_loop_candidates(frames, guess, std::span(&candidate, 1), options);
  ASSERT_EQ(far.size(), 1u);
  EXPECT_EQ(far[0].verdict, LoopVerdict::kTooFarFromGuess);
  EXPECT_STREQ(to_string(far[0].verdict), "too far from the guess");
  options.max_drift_fraction = std::numeric_limits<double>::infinity();
  const auto kept = validate_loop_candidates(frames, guess, std::span(&candidate, 1), options);
  ASSERT_EQ(kept[0].verdict, LoopVerdict::kAccepted);
  const Eigen::Isometry3d error = T_ij.inverse() * kept[0].registration.T_target_source;
  EXPECT_LT(error.translation().norm(), 0.2);
  options.max_drift_fraction = 0.0;
  try {
    validate_loop_candidates(frames, guess, std::span(&candidate, 1), options);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(),
                 "loop closure: max_drift_fraction must be > 0 (infinity: no limit), got 0");
  }
}

TEST(LoopClosureTest, BadInputIsNamed) {
  const DriftingDrive& d = drifting_drive();
  LoopClosureOptions options;
  FrameStore frames(d.pipeline.frames);
  const std::span<const Eigen::Isometry3d> fewer(d.guess.data(), 10);
  try {
    close_loops(frames, fewer, options);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "loop closure: 100 frames but 10 poses");
  }
  options.min_inlier_fraction = 1.5;
  try {
    find_loop_candidates(frames, d.guess, options);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "loop closure: min_inlier_fraction must be in [0, 1], got 1.5");
  }
  EXPECT_STREQ(to_string(LoopVerdict::kFewInliers), "few inliers");
  // A validation run elsewhere (LoopClosureStages) that answers for other candidates is refused.
  options.min_inlier_fraction = 0.8;
  std::size_t asked = 0;
  LoopClosureStages stages;
  stages.validate = [&](std::span<const LoopCandidate> candidates,
                        std::span<const Eigen::Isometry3d>, const LoopClosureOptions&) {
    asked = candidates.size();
    return std::vector<LoopCheck>(candidates.size() + 1);
  };
  try {
    close_loops(frames, d.guess, options, {}, stages);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "loop closure: the validation returned " +
                                         std::to_string(asked + 1) + " checks for " +
                                         std::to_string(asked) + " candidates");
  }
  EXPECT_GT(asked, 0u);
  // Descriptors made elsewhere: one per frame, of the options' shape.
  std::vector<ScanContext> descriptors(d.guess.size() - 1);
  try {
    find_loop_candidates(descriptors, d.guess, options);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "loop closure: 99 descriptors but 100 poses");
  }
  descriptors.resize(d.guess.size());
  descriptors[7].valid = true;
  descriptors[7].rings = 20;
  descriptors[7].sectors = 30;
  try {
    find_loop_candidates(descriptors, d.guess, options);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "loop closure: the descriptor of frame 7 is not 20 rings by 60 sectors");
  }
}

}  // namespace
}  // namespace carat
