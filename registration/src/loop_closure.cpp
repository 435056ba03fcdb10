#include "carat/registration/loop_closure.hpp"

#include <tbb/info.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <nanoflann.hpp>
#include <string>
#include <utility>

#include "carat/base/error.hpp"
#include "parallel.hpp"

namespace carat {
namespace {

/// nanoflann's dataset adaptor over the ring keys of the frames that have a descriptor.
struct RingKeys {
  std::vector<float> keys;  // count x rings
  std::size_t rings = 0;
  std::size_t kdtree_get_point_count() const { return rings ? keys.size() / rings : 0; }
  float kdtree_get_pt(std::size_t i, std::size_t dim) const { return keys[i * rings + dim]; }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};

using RingKeyTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, RingKeys>, RingKeys, -1,
                                        std::uint32_t>;

void check_counts(std::size_t frames, std::size_t poses) {
  if (frames != poses) {
    throw Error("loop closure: " + std::to_string(frames) + " frames but " + std::to_string(poses) +
                " poses");
  }
}

void check_options(const LoopClosureOptions& o) {
  const auto fail = [](const std::string& what, const std::string& rule, double value) {
    char text[32];
    std::snprintf(text, sizeof(text), "%g", value);
    throw Error("loop closure: " + what + " must be " + rule + ", got " + text);
  };
  if (!(std::isfinite(o.exclude_recent_m) && o.exclude_recent_m >= 0.0))
    fail("exclude_recent_m", "finite and >= 0 (metres)", o.exclude_recent_m);
  if (o.ring_key_candidates < 1) fail("ring_key_candidates", ">= 1", o.ring_key_candidates);
  if (!(o.max_descriptor_distance >= 0.0 && o.max_descriptor_distance <= 2.0))
    fail("max_descriptor_distance", "in [0, 2]", o.max_descriptor_distance);
  if (!(std::isfinite(o.max_correspondence_distance) && o.max_correspondence_distance > 0.0))
    fail("max_correspondence_distance", "finite and > 0 (metres)", o.max_correspondence_distance);
  if (!(o.min_inlier_fraction >= 0.0 && o.min_inlier_fraction <= 1.0))
    fail("min_inlier_fraction", "in [0, 1]", o.min_inlier_fraction);
  if (!(o.max_drift_fraction > 0.0))
    fail("max_drift_fraction", "> 0 (infinity: no limit)", o.max_drift_fraction);
  if (o.num_threads < 1) fail("num_threads", ">= 1", o.num_threads);
}

Eigen::Isometry3d yaw_pose(double yaw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

/// GICP from one start: a coarse stage (three times the distance), then the final one.
/// Returns false when either stage finds too few pairs.
bool align_from(const Frame& target, const Frame& source, const Eigen::Isometry3d& start,
                const LoopClosureOptions& options, AlignResult* result) {
  AlignSettings settings;
  settings.max_correspondence_distance = 3.0 * options.max_correspondence_distance;
  try {
    const AlignResult coarse =
        align(target.cloud(), target.tree(), source.cloud(), start, settings);
    settings.max_correspondence_distance = options.max_correspondence_distance;
    *result =
        align(target.cloud(), target.tree(), source.cloud(), coarse.T_target_source, settings);
  } catch (const Error&) {
    return false;
  }
  return true;
}

/// Distance travelled along the guess up to each frame (metres; 0 at frame 0).
std::vector<double> path_travel(std::span<const Eigen::Isometry3d> T_world_guess) {
  std::vector<double> travel(T_world_guess.size(), 0.0);
  for (std::size_t k = 1; k < travel.size(); ++k) {
    travel[k] = travel[k - 1] +
                (T_world_guess[k].translation() - T_world_guess[k - 1].translation()).norm();
  }
  return travel;
}

}  // namespace

const char* to_string(LoopVerdict verdict) {
  switch (verdict) {
    case LoopVerdict::kAccepted:
      return "accepted";
    case LoopVerdict::kNotConverged:
      return "not converged";
    case LoopVerdict::kDegenerate:
      return "degenerate";
    case LoopVerdict::kFewInliers:
      return "few inliers";
    case LoopVerdict::kTooFarFromGuess:
      return "too far from the guess";
  }
  return "unknown";
}

std::vector<LoopCandidate> find_loop_candidates(FrameStore& frames,
                                                std::span<const Eigen::Isometry3d> T_world_guess,
                                                const LoopClosureOptions& options,
                                                std::vector<int>* sparse_frames) {
  check_counts(frames.size(), T_world_guess.size());
  check_options(options);
  const std::size_t n = frames.size();
  std::vector<ScanContext> descriptors(n);
  const int threads = std::clamp(options.num_threads, 1, tbb::info::default_concurrency());
  tbb::task_arena arena(threads);
  arena.execute([&] {
    internal::parallel_for_each_index(n, [&](std::size_t k) {
      descriptors[k] = make_scan_context(frames.get(k)->cloud(), options.descriptor);
    });
  });
  return find_loop_candidates(descriptors, T_world_guess, options, sparse_frames);
}

std::vector<LoopCandidate> find_loop_candidates(std::span<const ScanContext> descriptors,
                                                std::span<const Eigen::Isometry3d> T_world_guess,
                                                const LoopClosureOptions& options,
                                                std::vector<int>* sparse_frames) {
  if (descriptors.size() != T_world_guess.size()) {
    throw Error("loop closure: " + std::to_string(descriptors.size()) + " descriptors but " +
                std::to_string(T_world_guess.size()) + " poses");
  }
  check_options(options);
  const std::size_t n = descriptors.size();
  for (std::size_t k = 0; k < n; ++k) {
    const ScanContext& d = descriptors[k];
    if (d.valid &&
        (d.rings != options.descriptor.rings || d.sectors != options.descriptor.sectors ||
         d.ring_key.size() != static_cast<std::size_t>(d.rings) ||
         d.bins.size() !=
             static_cast<std::size_t>(d.rings) * static_cast<std::size_t>(d.sectors))) {
      throw Error("loop closure: the descriptor of frame " + std::to_string(k) + " is not " +
                  std::to_string(options.descriptor.rings) + " rings by " +
                  std::to_string(options.descriptor.sectors) + " sectors");
    }
  }
  const std::vector<double> travel = path_travel(T_world_guess);
  const int threads = std::clamp(options.num_threads, 1, tbb::info::default_concurrency());
  tbb::task_arena arena(threads);
  RingKeys keys;
  keys.rings = static_cast<std::size_t>(options.descriptor.rings);
  std::vector<int> tree_frame;  // tree index -> frame
  for (std::size_t k = 0; k < n; ++k) {
    if (!descriptors[k].valid) {
      if (sparse_frames) sparse_frames->push_back(static_cast<int>(k));
      continue;
    }
    keys.keys.insert(keys.keys.end(), descriptors[k].ring_key.begin(),
                     descriptors[k].ring_key.end());
    tree_frame.push_back(static_cast<int>(k));
  }
  if (tree_frame.empty()) return {};
  const RingKeyTree tree(static_cast<int>(keys.rings), keys,
                         nanoflann::KDTreeSingleIndexAdaptorParams(10));
  const std::size_t total = tree_frame.size();

  std::vector<LoopCandidate> best(n);
  std::vector<unsigned char> found(n, 0);
  arena.execute([&] {
    internal::parallel_for_each_index(n, [&](std::size_t j) {
      if (!descriptors[j].valid) return;
      // Older frames far enough back along the path: a prefix of the frames.
      const double limit = travel[j] - options.exclude_recent_m;
      std::vector<int> allowed;
      const auto wanted = static_cast<std::size_t>(options.ring_key_candidates);
      for (std::size_t k = std::min(total, 4 * wanted);; k = std::min(total, 2 * k)) {
        std::vector<std::uint32_t> index(k);
        std::vector<float> distance(k);
        const std::size_t got =
            tree.knnSearch(descriptors[j].ring_key.data(), k, index.data(), distance.data());
        allowed.clear();
        for (std::size_t r = 0; r < got && allowed.size() < wanted; ++r) {
          const int i = tree_frame[index[r]];
          if (static_cast<std::size_t>(i) < j && travel[static_cast<std::size_t>(i)] <= limit)
            allowed.push_back(i);
        }
        if (allowed.size() >= wanted || k == total) break;
      }
      for (const int i : allowed) {
        const ScanContextMatch match =
            match_scan_contexts(descriptors[j], descriptors[static_cast<std::size_t>(i)]);
        if (match.distance > options.max_descriptor_distance) continue;
        LoopCandidate& b = best[j];
        const bool better = !found[j] || match.distance < b.descriptor_distance ||
                            (match.distance == b.descriptor_distance && i < b.pair.target);
        if (!better) continue;
        found[j] = 1;
        b.pair = FramePair{i, static_cast<int>(j), 0.0};
        b.descriptor_distance = match.distance;
        b.yaw = -match.yaw;  // match.yaw is T_source_target's; the loop is T_target_source
      }
    });
  });
  std::vector<LoopCandidate> out;
  for (std::size_t j = 0; j < n; ++j)
    if (found[j]) out.push_back(best[j]);
  return out;
}

std::vector<LoopCheck> validate_loop_candidates(FrameStore& frames,
                                                std::span<const Eigen::Isometry3d> T_world_guess,
                                                std::span<const LoopCandidate> candidates,
                                                const LoopClosureOptions& options) {
  check_counts(frames.size(), T_world_guess.size());
  check_options(options);
  std::vector<LoopCheck> checks(candidates.size());
  const std::vector<double> travel = path_travel(T_world_guess);
  const int threads = std::clamp(options.num_threads, 1, tbb::info::default_concurrency());
  tbb::task_arena arena(threads);
  arena.execute([&] {
    internal::parallel_for_each_index(candidates.size(), [&](std::size_t c) {
      const LoopCandidate& candidate = candidates[c];
      const auto i = static_cast<std::size_t>(candidate.pair.target);
      const auto j = static_cast<std::size_t>(candidate.pair.source);
      if (i >= frames.size() || j >= frames.size() || i == j) {
        throw Error("loop closure: candidate " + std::to_string(i) + " - " + std::to_string(j) +
                    " names a missing frame");
      }
      const std::shared_ptr<const Frame> target_frame = frames.get(i);
      const std::shared_ptr<const Frame> source_frame = frames.get(j);
      const Frame& target = *target_frame;
      const Frame& source = *source_frame;
      const Eigen::Isometry3d starts[2] = {yaw_pose(candidate.yaw),
                                           T_world_guess[i].inverse() * T_world_guess[j]};
      LoopCheck& check = checks[c];
      check.candidate = candidate;
      bool any = false;
      AlignResult chosen;
      for (const Eigen::Isometry3d& start : starts) {
        AlignResult result;
        if (!align_from(target, source, start, options, &result) || !result.converged) continue;
        if (!any || result.num_correspondences > chosen.num_correspondences) chosen = result;
        any = true;
      }
      if (!any) return;
      check.inlier_fraction =
          static_cast<double>(chosen.num_correspondences) / static_cast<double>(source.size());
      PairRegistration& r = check.registration;
      r.pair = candidate.pair;
      r.T_target_source = chosen.T_target_source;
      r.H = chosen.H;
      r.error = chosen.error;
      r.num_correspondences = chosen.num_correspondences;
      r.iterations = chosen.iterations;
      r.converged = chosen.converged;
      r.constrained_dof = chosen.constrained_dof;
      if (chosen.constrained_dof < 6) {
        check.verdict = LoopVerdict::kDegenerate;
      } else if (check.inlier_fraction < options.min_inlier_fraction) {
        check.verdict = LoopVerdict::kFewInliers;
      } else if ((starts[1].inverse() * chosen.T_target_source).translation().norm() >
                 options.max_drift_fraction * std::abs(travel[j] - travel[i])) {
        check.verdict = LoopVerdict::kTooFarFromGuess;
      } else {
        check.verdict = LoopVerdict::kAccepted;
      }
    });
  });
  return checks;
}

LoopClosureResult close_loops(FrameStore& frames, std::span<const Eigen::Isometry3d> T_world_guess,
                              const LoopClosureOptions& options,
                              const std::function<void(std::size_t, std::size_t)>& progress) {
  return close_loops(frames, T_world_guess, options, progress, LoopClosureStages{});
}

LoopClosureResult close_loops(FrameStore& frames, std::span<const Eigen::Isometry3d> T_world_guess,
                              const LoopClosureOptions& options,
                              const std::function<void(std::size_t, std::size_t)>& progress,
                              const LoopClosureStages& stages) {
  check_counts(frames.size(), T_world_guess.size());
  if (frames.size() < 2) {
    throw Error("loop closure: needs at least 2 frames, got " + std::to_string(frames.size()));
  }
  check_options(options);
  LoopClosureResult out;
  if (stages.describe) {
    const std::vector<ScanContext> descriptors = stages.describe(frames.size(), options.descriptor);
    out.candidates = find_loop_candidates(descriptors, T_world_guess, options, &out.sparse_frames);
  } else {
    out.candidates = find_loop_candidates(frames, T_world_guess, options, &out.sparse_frames);
  }
  if (progress) progress(1, 3);
  out.checks = stages.validate
                   ? stages.validate(out.candidates, T_world_guess, options)
                   : validate_loop_candidates(frames, T_world_guess, out.candidates, options);
  if (out.checks.size() != out.candidates.size()) {
    throw Error("loop closure: the validation returned " + std::to_string(out.checks.size()) +
                " checks for " + std::to_string(out.candidates.size()) + " candidates");
  }
  for (const LoopCheck& check : out.checks)
    if (check.verdict == LoopVerdict::kAccepted) out.loops.push_back(check.registration);
  if (progress) progress(2, 3);
  std::vector<FramePair> consecutive;
  for (int k = 0; k + 1 < static_cast<int>(frames.size()); ++k)
    consecutive.push_back(FramePair{k, k + 1, 0.0});
  AlignSettings settings;
  settings.max_correspondence_distance = options.max_correspondence_distance;
  out.odometry =
      stages.register_consecutive
          ? stages.register_consecutive(consecutive, T_world_guess, settings)
          : register_pairs(frames, consecutive, T_world_guess, settings, options.num_threads);
  if (out.odometry.size() != consecutive.size()) {
    throw Error("loop closure: the consecutive registrations returned " +
                std::to_string(out.odometry.size()) + " pairs for " +
                std::to_string(consecutive.size()));
  }
  out.T_world_frame.assign(T_world_guess.begin(), T_world_guess.end());
  if (!out.loops.empty()) {
    std::vector<PairRegistration> edges = out.odometry;
    edges.insert(edges.end(), out.loops.begin(), out.loops.end());
    PoseGraphBaselineOptions plain = options.graph;
    plain.cauchy_scale = 0.0;
    plain.solver.num_threads = options.num_threads;
    const PoseGraphBaselineResult first = optimize_pose_graph_baseline(T_world_guess, edges, plain);
    PoseGraphBaselineOptions robust = options.graph;
    robust.solver.num_threads = options.num_threads;
    const PoseGraphBaselineResult second =
        optimize_pose_graph_baseline(first.T_world_frame, edges, robust);
    out.T_world_frame = second.T_world_frame;
    out.summary = second.summary;
  }
  if (progress) progress(3, 3);
  return out;
}

}  // namespace carat
