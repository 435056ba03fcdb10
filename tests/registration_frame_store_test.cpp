// FrameStore: frames on demand under a byte cap (least recently used dropped first, frames in use
// kept, loader errors passed on and retried, prefetches that never wait, points read alone for the
// overlap tests), the locality order of pairs, and the dense graph, factors, registration and loop
// closure from a capped store equal to the resident run; the dense graph measured in shares reading
// only the frames each share names.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <numeric>
#include <string>
#include <thread>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/registration/dense_graph.hpp"
#include "carat/registration/frame_store.hpp"
#include "carat/registration/global_registration.hpp"
#include "carat/registration/pair_registration.hpp"
#include "carat/sim/pipeline.hpp"
#include "carat/solver/se3.hpp"
#include "registration_test_drive.hpp"
#include "test_support.hpp"

namespace carat {
namespace {

using test::error_of;
using ::testing::HasSubstr;

/// 24 frames of one lap (8 m apart), preprocessed once; the stores below hand these out.
struct Drive {
  std::vector<std::shared_ptr<const Frame>> frames;
  std::vector<Eigen::Isometry3d> initial;
};

const Drive& drive() {
  static const Drive d = [] {
    SyntheticPipeline pipeline = test::simulate_test_drive(
        11, 24, 1, {.seed = 5, .translation_sigma = 0.01, .rotation_sigma_deg = 0.05});
    return Drive{std::move(pipeline.frames), std::move(pipeline.T_world_drift)};
  }();
  return d;
}

/// A fresh frame with drive()'s frame k's points and covariances (as a loader reads one).
std::shared_ptr<const Frame> copy_of_frame(std::size_t k) {
  auto frame = std::make_shared<Frame>(PointCloud(drive().frames[k]->cloud()));
  frame->set_name("frame " + std::to_string(k));
  return frame;
}

/// A store of copies of drive()'s frames that counts its loader's calls, capped at
/// `frames_held` times the largest frame's bytes; with `same_frame`, every index gets a copy of
/// frame 0 (all frames the same size).
struct CountingStore {
  std::shared_ptr<std::atomic<int>> calls = std::make_shared<std::atomic<int>>(0);
  std::unique_ptr<FrameStore> store;
  explicit CountingStore(double frames_held, bool same_frame = false) {
    std::size_t largest = 0;
    for (std::size_t k = 0; k < drive().frames.size(); ++k)
      largest = std::max(largest, copy_of_frame(same_frame ? 0 : k)->memory_bytes());
    auto counter = calls;
    store = std::make_unique<FrameStore>(
        drive().frames.size(),
        [counter, same_frame](std::size_t k) {
          ++*counter;
          return copy_of_frame(same_frame ? 0 : k);
        },
        static_cast<std::size_t>(frames_held * static_cast<double>(largest)));
  }
};

TEST(FrameStoreTest, LoadsOnDemandAndDropsTheLeastRecentlyUsed) {
  CountingStore s(3.5, true);  // room for three frames
  FrameStore& store = *s.store;
  EXPECT_FALSE(store.resident());
  EXPECT_EQ(store.get(0)->cloud().points, drive().frames[0]->cloud().points);
  store.get(1);
  store.get(2);
  store.get(0);  // 0 is now the most recently used; 1 the least
  EXPECT_EQ(*s.calls, 3);
  store.get(3);  // drops 1
  store.get(0);
  store.get(2);
  EXPECT_EQ(*s.calls, 4);
  store.get(1);  // read again
  EXPECT_EQ(*s.calls, 5);
  const FrameStoreStats stats = store.stats();
  EXPECT_EQ(stats.requests, 8u);
  EXPECT_EQ(stats.hits, 3u);
  EXPECT_EQ(stats.loads, 5u);
  EXPECT_EQ(stats.evictions, 2u);
  EXPECT_LE(stats.peak_bytes, stats.max_bytes);
}

TEST(FrameStoreTest, FramesInUseStayAndCount) {
  CountingStore s(1.5, true);  // room for one frame
  FrameStore& store = *s.store;
  const std::shared_ptr<const Frame> held = store.get(0);
  store.get(1);  // 0 is held by the caller: it stays, and the cap is exceeded while it is
  EXPECT_GT(store.stats().peak_bytes, store.stats().max_bytes);
  store.get(0);
  EXPECT_EQ(*s.calls, 2);
}

TEST(FrameStoreTest, ReleasingTheCacheKeepsOnlyFramesInUse) {
  CountingStore s(3.5, true);  // room for three frames
  FrameStore& store = *s.store;
  const std::shared_ptr<const Frame> held = store.get(0);
  store.get(1);
  store.get(2);
  store.release_cached();  // 1 and 2 go; 0 is held
  store.get(0);
  EXPECT_EQ(*s.calls, 3);
  store.get(1);  // read again
  store.get(2);
  EXPECT_EQ(*s.calls, 5);
  EXPECT_EQ(store.stats().evictions, 0u);  // not dropped for the cap
  // A resident store keeps its frames.
  FrameStore resident = resident_store(drive().frames);
  resident.release_cached();
  EXPECT_EQ(resident.get(1), drive().frames[1]);
}

TEST(FrameStoreTest, LoaderErrorsPassThroughAndAreRetried) {
  int calls = 0;
  FrameStore store(
      2,
      [&](std::size_t k) -> std::shared_ptr<const Frame> {
        if (++calls == 1) throw Error("frame " + std::to_string(k) + ".bin: truncated");
        return copy_of_frame(k);
      },
      0);
  EXPECT_EQ(error_of([&] { store.get(1); }), "frame 1.bin: truncated");
  EXPECT_EQ(store.get(1)->name(), "frame 1");
  EXPECT_THAT(error_of([&] { store.get(2); }), HasSubstr("frame 2 requested of 2"));
  EXPECT_THAT(
      error_of([] { FrameStore nulls(std::vector<std::shared_ptr<const Frame>>{nullptr}); }),
      HasSubstr("frame 0 is null"));
}

TEST(FrameStoreTest, PrefetchReadsOnlyWhatIsNeitherCachedNorBeingRead) {
  CountingStore s(2.5, true);  // room for two frames
  FrameStore& store = *s.store;
  EXPECT_TRUE(store.prefetch(0));
  EXPECT_FALSE(store.prefetch(0));  // cached
  EXPECT_EQ(*s.calls, 1);
  store.get(0);  // a hit
  EXPECT_TRUE(store.prefetch(1));
  EXPECT_TRUE(store.prefetch(2));  // drops 0, the least recently used
  store.get(0);                    // read again
  EXPECT_EQ(*s.calls, 4);
  EXPECT_FALSE(store.prefetch(99));  // out of range: nothing to read
  const FrameStoreStats stats = store.stats();
  EXPECT_EQ(stats.requests, 2u);
  EXPECT_EQ(stats.hits, 1u);
  EXPECT_EQ(stats.loads, 4u);
  EXPECT_EQ(stats.evictions, 2u);
  // A resident store reads nothing.
  FrameStore resident = resident_store(drive().frames);
  EXPECT_FALSE(resident.prefetch(0));
}

TEST(FrameStoreTest, PrefetchDropsLoaderErrorsAndGetThrowsThem) {
  int calls = 0;
  FrameStore store(
      2,
      [&](std::size_t k) -> std::shared_ptr<const Frame> {
        if (++calls <= 2) throw Error("frame " + std::to_string(k) + ".bin: truncated");
        return copy_of_frame(k);
      },
      0);
  EXPECT_FALSE(store.prefetch(1));  // the error is dropped, the frame stays unread
  EXPECT_EQ(error_of([&] { store.get(1); }), "frame 1.bin: truncated");
  EXPECT_EQ(store.get(1)->name(), "frame 1");
  EXPECT_EQ(calls, 3);
  EXPECT_EQ(store.stats().loads, 1u);
}

TEST(FrameStoreTest, PrefetchSkipsAFrameAnotherThreadIsReading) {
  std::mutex mutex;
  std::condition_variable changed;
  bool reading = false, release = false;
  std::atomic<int> calls{0};
  FrameStore store(
      1,
      [&](std::size_t k) -> std::shared_ptr<const Frame> {
        ++calls;
        std::unique_lock lock(mutex);
        reading = true;
        changed.notify_all();
        changed.wait(lock, [&] { return release; });
        return copy_of_frame(k);
      },
      0);
  std::thread reader([&] { store.get(0); });
  {
    std::unique_lock lock(mutex);
    changed.wait(lock, [&] { return reading; });
  }
  EXPECT_FALSE(store.prefetch(0));  // being read: returns at once instead of waiting
  {
    std::lock_guard lock(mutex);
    release = true;
  }
  changed.notify_all();
  reader.join();
  EXPECT_EQ(calls, 1);
  EXPECT_EQ(store.get(0)->name(), "frame 0");
  EXPECT_EQ(calls, 1);
}

TEST(FrameStoreTest, PointsComeFromTheCacheOrThePointsLoaderWithoutBuildingAFrame) {
  std::atomic<int> frames_read{0}, points_read{0};
  FrameStore store(
      3,
      [&](std::size_t k) {
        ++frames_read;
        return copy_of_frame(k);
      },
      [&](std::size_t k) {
        ++points_read;
        if (k == 2) throw Error("scan 2: unreadable");
        PointCloud cloud;
        cloud.points = drive().frames[k]->cloud().points;
        return cloud;
      },
      0);
  EXPECT_EQ(store.points(0)->points, drive().frames[0]->cloud().points);
  EXPECT_EQ(points_read, 1);
  EXPECT_EQ(frames_read, 0);
  store.points(0);  // not kept: read again
  EXPECT_EQ(points_read, 2);
  const std::shared_ptr<const Frame> frame = store.get(1);
  EXPECT_EQ(store.points(1).get(), &frame->cloud()) << "a cached frame's own cloud";
  EXPECT_EQ(points_read, 2);
  EXPECT_EQ(error_of([&] { store.points(2); }), "scan 2: unreadable");
  EXPECT_EQ(error_of([&] { store.points(3); }), "frame store: frame 3 requested of 3");
  const FrameStoreStats stats = store.stats();
  EXPECT_EQ(stats.loads, 1u);
  EXPECT_EQ(stats.point_loads, 2u);
  EXPECT_EQ(stats.requests, 1u);
  EXPECT_EQ(error_of([] { FrameStore(1, copy_of_frame, FrameStore::PointsLoader{}, 0); }),
            "frame store: no points loader given");
  // Without a points loader: the whole frame, which then stays.
  CountingStore plain(1e9);
  EXPECT_EQ(plain.store->points(4)->covariances, drive().frames[4]->cloud().covariances);
  plain.store->points(4);
  EXPECT_EQ(*plain.calls, 1);
  EXPECT_EQ(plain.store->stats().point_loads, 0u);
}

TEST(FrameStoreTest, TheDenseGraphReadsPointsAloneAndDownsamplingKeepsTheFramesPoints) {
  const Drive& d = drive();
  FrameStore resident(d.frames);
  std::atomic<int> frames_read{0};
  FrameStore store(
      d.frames.size(),
      [&](std::size_t k) {
        ++frames_read;
        return copy_of_frame(k);
      },
      [&](std::size_t k) {
        PointCloud cloud;
        cloud.points = d.frames[k]->cloud().points;
        return cloud;
      },
      std::size_t{1} << 40);
  const std::vector<FramePair> whole = build_dense_graph(resident, d.initial);
  const std::vector<FramePair> from_points = build_dense_graph(store, d.initial);
  ASSERT_EQ(whole.size(), from_points.size());
  for (std::size_t k = 0; k < whole.size(); ++k) {
    EXPECT_EQ(whole[k].target, from_points[k].target);
    EXPECT_EQ(whole[k].source, from_points[k].source);
    EXPECT_EQ(whole[k].overlap, from_points[k].overlap);
  }
  EXPECT_EQ(frames_read, 0);
  EXPECT_EQ(store.stats().point_loads, d.frames.size());
  // downsample_frame_points() keeps what preprocess_frame() keeps, and fails as it does.
  PointCloud raw;
  raw.points = d.frames[3]->cloud().points;
  PreprocessOptions options;
  options.voxel_size = 0.7;
  EXPECT_EQ(downsample_frame_points(raw, options, "scan 3").points,
            preprocess_frame(raw, options, "scan 3")->cloud().points);
  options.min_points = 1000000;
  EXPECT_THAT(error_of([&] { downsample_frame_points(raw, options, "scan 3"); }),
              HasSubstr("scan 3: only "));
  EXPECT_EQ(error_of([&] { downsample_frame_points(raw, options, "scan 3"); }),
            error_of([&] { preprocess_frame(raw, options, "scan 3"); }));
}

TEST(FrameStoreTest, LocalityOrderIsAPermutationThatKeepsCellsTogether) {
  FrameStore frames(drive().frames);
  const std::vector<FramePair> pairs = build_dense_graph(frames, drive().initial);
  const std::vector<std::size_t> order = locality_order(pairs, drive().initial);
  std::vector<std::size_t> sorted = order;
  std::sort(sorted.begin(), sorted.end());
  std::vector<std::size_t> identity(pairs.size());
  std::iota(identity.begin(), identity.end(), std::size_t{0});
  EXPECT_EQ(sorted, identity);
  EXPECT_THAT(error_of([&] { locality_order(pairs, drive().initial, 0.0); }),
              HasSubstr("cell_size must be finite and > 0"));
  const std::vector<FramePair> bad = {{0, 99, 0.0}};
  EXPECT_THAT(error_of([&] { locality_order(bad, drive().initial); }),
              HasSubstr("pair (0, 99) names a frame without a pose"));
}

TEST(FrameStoreTest, ACappedStoreGivesTheResidentResults) {
  const Drive& d = drive();
  FrameStore resident_store(d.frames);
  CountingStore s(4.0);
  const std::vector<FramePair> pairs = build_dense_graph(resident_store, d.initial);
  const std::vector<FramePair> streamed_pairs = build_dense_graph(*s.store, d.initial);
  ASSERT_EQ(pairs.size(), streamed_pairs.size());
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    EXPECT_EQ(pairs[k].target, streamed_pairs[k].target);
    EXPECT_EQ(pairs[k].source, streamed_pairs[k].source);
    EXPECT_EQ(pairs[k].overlap, streamed_pairs[k].overlap);
  }
  for (const ResidualSampling sampling : {ResidualSampling::kExact, ResidualSampling::kLossless}) {
    GlobalRegistrationOptions options;
    options.sampling = sampling;
    options.num_threads = 2;
    options.rounds = 2;
    const GlobalRegistrationResult resident =
        optimize_registration(resident_store, pairs, d.initial, options);
    const GlobalRegistrationResult streamed =
        optimize_registration(*s.store, pairs, d.initial, options);
    ASSERT_EQ(resident.T_world_frame.size(), streamed.T_world_frame.size());
    for (std::size_t i = 0; i < resident.T_world_frame.size(); ++i)
      EXPECT_EQ(resident.T_world_frame[i].matrix(), streamed.T_world_frame[i].matrix()) << i;
    EXPECT_EQ(resident.summary.final_cost, streamed.summary.final_cost);
    EXPECT_EQ(resident.factor_costs, streamed.factor_costs);
  }
  const FrameStoreStats stats = s.store->stats();
  EXPECT_GT(stats.evictions, 0u);
  EXPECT_LE(stats.peak_bytes, stats.max_bytes);
  // Pairwise GICP (the pose-graph baselines) too.
  const auto a = register_pairs(resident_store, pairs, d.initial, AlignSettings{}, 2);
  const auto b = register_pairs(*s.store, pairs, d.initial, AlignSettings{}, 2);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k)
    EXPECT_EQ(a[k].T_target_source.matrix(), b[k].T_target_source.matrix()) << k;
}

TEST(FrameStoreTest, SharesOfTheCandidatesMeasureTheWholeGraphReadingOnlyTheirFrames) {
  const Drive& d = drive();
  FrameStore resident(d.frames);
  const std::vector<FramePair> whole = build_dense_graph(resident, d.initial);
  std::vector<FramePair> candidates = dense_graph_candidates(d.initial);
  ASSERT_GT(candidates.size(), whole.size());
  // Two shares, each measured from its own store, as two ranks of an MPI job do.
  const std::size_t half = candidates.size() / 2;
  std::vector<FramePair> first(candidates.begin(), candidates.begin() + half);
  std::vector<FramePair> second(candidates.begin() + half, candidates.end());
  int fewest = static_cast<int>(d.frames.size());
  for (std::vector<FramePair>* share : {&first, &second}) {
    CountingStore s(1e9);
    measure_overlaps(*s.store, d.initial, *share);
    std::vector<char> named(d.frames.size(), 0);
    for (const FramePair& pair : *share) {
      named[static_cast<std::size_t>(pair.target)] = 1;
      named[static_cast<std::size_t>(pair.source)] = 1;
    }
    EXPECT_EQ(*s.calls, std::count(named.begin(), named.end(), 1)) << "each named frame once";
    fewest = std::min(fewest, s.calls->load());
  }
  EXPECT_LT(fewest, static_cast<int>(d.frames.size())) << "a share that names fewer frames";
  std::copy(first.begin(), first.end(), candidates.begin());
  std::copy(second.begin(), second.end(), candidates.begin() + static_cast<std::ptrdiff_t>(half));
  const std::vector<FramePair> joined = select_dense_graph(candidates);
  ASSERT_EQ(joined.size(), whole.size());
  for (std::size_t k = 0; k < whole.size(); ++k) {
    EXPECT_EQ(joined[k].target, whole[k].target);
    EXPECT_EQ(joined[k].source, whole[k].source);
    EXPECT_EQ(joined[k].overlap, whole[k].overlap);
  }
  std::vector<FramePair> bad = {{0, 24, 0.0}};
  EXPECT_THAT(error_of([&] { measure_overlaps(resident, d.initial, bad); }),
              HasSubstr("pair (0, 24) names a frame out of range (24 frames)"));
}

TEST(FrameStoreTest, ASubsetOfFactorsEqualsTheSameFactorsOfTheWhole) {
  const Drive& d = drive();
  FrameStore resident(d.frames);
  const std::vector<FramePair> pairs = build_dense_graph(resident, d.initial);
  GlobalRegistrationOptions options;
  options.num_threads = 2;
  const auto all = build_registration_factors(resident, pairs, {}, d.initial, options);
  const std::vector<std::size_t> some = {pairs.size() - 1, 3, 0};
  CountingStore s(2.0);
  const auto part = build_registration_factors(*s.store, pairs, some, d.initial, options);
  ASSERT_EQ(part.size(), some.size());
  for (std::size_t p = 0; p < some.size(); ++p) {
    const FramePair& pair = pairs[some[p]];
    const double* values[2] = {nullptr, nullptr};
    std::array<double, 7> ti{}, tj{};
    se3::to_storage(d.initial[static_cast<std::size_t>(pair.target)], ti.data());
    se3::to_storage(d.initial[static_cast<std::size_t>(pair.source)], tj.data());
    values[0] = ti.data();
    values[1] = tj.data();
    EXPECT_EQ(part[p].block->squared_norm(values), all[some[p]].block->squared_norm(values));
    EXPECT_EQ(part[p].correspondences, all[some[p]].correspondences);
  }
  EXPECT_THAT(error_of([&] {
                const std::vector<std::size_t> out_of_range = {pairs.size()};
                build_registration_factors(resident, pairs, out_of_range, d.initial, options);
              }),
              HasSubstr("factor index"));
}

}  // namespace
}  // namespace carat
