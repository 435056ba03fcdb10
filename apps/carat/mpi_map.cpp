#include "mpi_map.hpp"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <limits>
#include <new>
#include <numeric>
#include <string>
#include <thread>
#include <utility>

#include "carat/base/error.hpp"
#include "carat/base/field_count.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/registration/dense_graph.hpp"
#include "carat/registration/frame_store.hpp"
#include "carat/registration/scan_context.hpp"
#include "cli_support.hpp"
#include "mpi_launch.hpp"
#include "mpi_messages.hpp"

#if CARAT_WITH_MPI
#include <mpi.h>
#endif

namespace carat::cli {
namespace {

enum Command : std::uint64_t {
  kStop = 0,
  kBuild = 1,        // build and hold a round's factors
  kOverlaps = 2,     // measure the dense graph's candidates
  kLinearize = 3,    // stream the held factors' linearization records at the poses sent
  kCosts = 4,        // stream their costs
  kFactorCosts = 5,  // answer their costs per correspondence
  kLoops = 6,        // the loop step: describe frames, validate candidates or register pairs
};

#if CARAT_WITH_MPI

/// Frames read and preprocessed on demand as rank 0 read them, under rank 0's cap (none: each
/// kept once read), so that a rank reads only the frames of its share; first checks that every
/// file has the size rank 0 saw (check_same_files()).
std::shared_ptr<FrameStore> frames_from(const MpiFrameSource& source) {
  check_same_files(source);
  OpenScansOptions scans = source.scans;
  scans.preprocess.num_threads = 1;
  if (scans.max_bytes == 0) scans.max_bytes = std::numeric_limits<std::size_t>::max();
  return open_scans(source.files, scans);
}

/// Scans the rank's store read from disk so far: whole frames and, for overlap tests, points
/// alone.
ScanReads scans_read(const FrameStore& store) {
  const FrameStoreStats stats = store.stats();
  return {stats.loads, stats.point_loads};
}

constexpr int kAnswerTag = 7;
constexpr std::size_t kChunk = std::size_t{1} << 30;  // MPI counts are int

/// One rank's share of a loop job (`indices` into its pairs), done with `threads` threads in
/// this process as close_loops() would, and its answer (`time` started after the job was read).
std::vector<std::byte> do_loop_share(FrameStore& store, const LoopJob& job,
                                     std::span<const std::size_t> indices, int threads,
                                     const Stopwatch& time) {
  if (job.options.kind == LoopWork::Kind::kDescribe) {
    std::vector<ScanContext> descriptors(indices.size());
    tbb::task_arena arena(std::max(1, threads));
    arena.execute([&] {
      tbb::parallel_for(std::size_t{0}, indices.size(), [&](std::size_t q) {
        const auto frame = static_cast<std::size_t>(job.pairs[indices[q]].target);
        descriptors[q] = make_scan_context(store.get(frame)->cloud(), job.options.descriptor);
      });
    });
    return encode_descriptors(descriptors, time.elapsed_s(), scans_read(store), peak_rss_bytes());
  }
  if (job.options.kind == LoopWork::Kind::kValidate) {
    std::vector<LoopCandidate> candidates;
    for (const std::size_t k : indices)
      candidates.push_back(
          LoopCandidate{job.pairs[k], job.options.descriptor_distance[k], job.options.yaw[k]});
    LoopClosureOptions options;
    options.max_correspondence_distance = job.options.max_correspondence_distance;
    options.min_inlier_fraction = job.options.min_inlier_fraction;
    options.max_drift_fraction = job.options.max_drift_fraction;
    options.num_threads = threads;
    std::vector<LoopCheck> checks;
    if (!candidates.empty())
      checks = validate_loop_candidates(store, job.T_world_frame, candidates, options);
    return encode_loop_checks(checks, time.elapsed_s(), scans_read(store), peak_rss_bytes());
  }
  std::vector<FramePair> pairs;
  for (const std::size_t k : indices) pairs.push_back(job.pairs[k]);
  std::vector<PairRegistration> registrations;
  if (!pairs.empty())
    registrations = register_pairs(store, pairs, job.T_world_frame, job.options.settings, threads);
  return encode_registrations(registrations, time.elapsed_s(), scans_read(store), peak_rss_bytes());
}

/// A failure the test suite asks a rank for (CARAT_MPI_TEST_FAULT="throw@K" or "abort@K": fail
/// the K-th linearization with an error, or die there as a crash would); at 0: none.
struct TestFault {
  std::size_t at = 0;
  bool abort = false;
};

TestFault test_fault() {
  const char* text = std::getenv("CARAT_MPI_TEST_FAULT");
  if (!text) return {};
  const std::string spec = text;
  TestFault fault;
  const std::size_t sign = spec.find('@');
  if (sign == std::string::npos) return {};
  fault.abort = spec.substr(0, sign) == "abort";
  fault.at = static_cast<std::size_t>(std::strtoull(spec.c_str() + sign + 1, nullptr, 10));
  return fault;
}

/// The poses rank 0 sends with a linearization, cost evaluation or factor-cost request.
std::vector<double> values_of(std::span<const std::byte> payload) {
  if (payload.size() % sizeof(double) != 0)
    throw Error("the poses from rank 0: garbled: " + std::to_string(payload.size()) + " bytes");
  std::vector<double> values(payload.size() / sizeof(double));
  std::memcpy(values.data(), payload.data(), payload.size());
  return values;
}

/// The poses as the bytes of a broadcast.
std::vector<std::byte> bytes_of(std::span<const double> values) {
  std::vector<std::byte> bytes(values.size_bytes());
  std::memcpy(bytes.data(), values.data(), values.size_bytes());
  return bytes;
}

/// Waits for a request without spinning a core that the builders or the solver could use.
void wait(MPI_Request* request) {
  int done = 0;
  auto pause = std::chrono::microseconds(20);
  for (;;) {
    MPI_Test(request, &done, MPI_STATUS_IGNORE);
    if (done) return;
    std::this_thread::sleep_for(pause);
    pause = std::min(pause * 2, std::chrono::microseconds(2000));
  }
}

/// Rank 0 sends (others receive) a command and its bytes.
void broadcast(std::uint64_t* command, std::vector<std::byte>* bytes) {
  std::uint64_t header[2] = {*command, bytes->size()};
  MPI_Request request;
  MPI_Ibcast(header, 2, MPI_UINT64_T, 0, MPI_COMM_WORLD, &request);
  wait(&request);
  *command = header[0];
  bytes->resize(static_cast<std::size_t>(header[1]));
  for (std::size_t at = 0; at < bytes->size(); at += kChunk) {
    const int count = static_cast<int>(std::min(kChunk, bytes->size() - at));
    MPI_Ibcast(bytes->data() + at, count, MPI_BYTE, 0, MPI_COMM_WORLD, &request);
    wait(&request);
  }
}

/// Sends an answer to rank 0, which takes it once its own share is built (the wait sleeps).
void send_answer(const std::vector<std::byte>& bytes) {
  std::uint64_t size = bytes.size();
  MPI_Request request;
  MPI_Isend(&size, 1, MPI_UINT64_T, 0, kAnswerTag, MPI_COMM_WORLD, &request);
  wait(&request);
  for (std::size_t at = 0; at < bytes.size(); at += kChunk) {
    const int count = static_cast<int>(std::min(kChunk, bytes.size() - at));
    MPI_Isend(bytes.data() + at, count, MPI_BYTE, 0, kAnswerTag, MPI_COMM_WORLD, &request);
    wait(&request);
  }
}

/// Receives rank `from`'s answer.
std::vector<std::byte> receive_answer(int from) {
  std::uint64_t size = 0;
  MPI_Request request;
  MPI_Irecv(&size, 1, MPI_UINT64_T, from, kAnswerTag, MPI_COMM_WORLD, &request);
  wait(&request);
  std::vector<std::byte> bytes(static_cast<std::size_t>(size));
  for (std::size_t at = 0; at < bytes.size(); at += kChunk) {
    const int count = static_cast<int>(std::min(kChunk, bytes.size() - at));
    MPI_Irecv(bytes.data() + at, count, MPI_BYTE, from, kAnswerTag, MPI_COMM_WORLD, &request);
    wait(&request);
  }
  return bytes;
}

#endif

}  // namespace

std::unique_ptr<MpiMapJob> MpiMapJob::start() {
  const int ranks = mpi_launch().size;
  if (ranks < 2) return nullptr;
#if CARAT_WITH_MPI
  int provided = 0;
  MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  return std::unique_ptr<MpiMapJob>(new MpiMapJob(rank, size));
#else
  throw Error("started by mpirun with " + std::to_string(ranks) +
              " ranks, but this carat was built without MPI (configure with -DCARAT_MPI=ON and "
              "OpenMPI's development files installed)");
#endif
}

MpiMapJob::~MpiMapJob() {
#if CARAT_WITH_MPI
  if (rank_ == 0) {
    std::uint64_t command = kStop;
    std::vector<std::byte> none;
    broadcast(&command, &none);
  }
  MPI_Finalize();
#endif
}

int MpiMapJob::serve(int threads) {
#if CARAT_WITH_MPI
  std::shared_ptr<FrameStore> store;
  std::unique_ptr<RegistrationShare> held;
  const TestFault fault = test_fault();
  std::size_t linearizations = 0;
  for (;;) {
    std::uint64_t command = kStop;
    std::vector<std::byte> payload;
    broadcast(&command, &payload);
    if (command == kLinearize || command == kCosts) {
      // A stream of runs, then its end; a failure ends it early, with the message.
      std::vector<std::byte> end = encode_done();
      try {
        if (!held) throw Error("holds no factors (no build job came first)");
        if (command == kLinearize && ++linearizations == fault.at) {
          if (fault.abort) std::abort();
          throw Error("failed as CARAT_MPI_TEST_FAULT asked, in linearization " +
                      std::to_string(linearizations));
        }
        const std::vector<double> values = values_of(payload);
        const BlockRecordSink send = [](std::size_t first, std::span<const double> records) {
          send_answer(encode_records(first, records));
        };
        if (command == kLinearize) {
          held->linearize(values, send);
        } else {
          held->costs(values, send);
        }
      } catch (const std::bad_alloc&) {
        end = encode_failure("out of memory");
      } catch (const std::exception& e) {
        end = encode_failure(e.what());
      }
      send_answer(end);
      continue;
    }
    if (command != kBuild && command != kOverlaps && command != kFactorCosts && command != kLoops)
      return 0;
    std::vector<std::byte> answer;
    try {
      // Each share's time from where rank 0's own starts: after the job is read.
      if (command == kFactorCosts) {
        if (!held) throw Error("holds no factors (no build job came first)");
        answer = encode_numbers(held->factor_costs(values_of(payload)), peak_rss_bytes());
      } else if (command == kLoops) {
        LoopJob job = decode_loop_job(payload);
        if (!store) store = frames_from(job.source);
        check_shares(job.shares.size());
        const Stopwatch time;
        const std::vector<std::size_t>& indices = job.shares[static_cast<std::size_t>(rank_)];
        answer = do_loop_share(*store, job, indices, threads, time);
      } else if (command == kOverlaps) {
        OverlapJob job = decode_overlap_job(payload);
        job.options.num_threads = threads;
        if (!store) store = frames_from(job.source);
        check_shares(job.shares.size());
        const Stopwatch time;
        std::vector<FramePair> share;
        for (const std::size_t k : job.shares[static_cast<std::size_t>(rank_)])
          share.push_back(job.pairs[k]);
        if (!share.empty()) measure_overlaps(*store, job.T_world_frame, share, job.options);
        answer = encode_overlaps(share, time.elapsed_s(), scans_read(*store), peak_rss_bytes());
      } else {
        BuildJob job = decode_job(payload);
        job.options.num_threads = threads;
        if (!store) store = frames_from(job.source);
        check_shares(job.shares.size());
        held.reset();  // the last round's factors go before this round's are built
        const Stopwatch time;
        const std::vector<std::size_t>& indices = job.shares[static_cast<std::size_t>(rank_)];
        std::vector<RegistrationFactor> factors;
        if (!indices.empty()) {
          factors = build_registration_factors(*store, job.pairs, indices, job.T_world_frame,
                                               job.options);
        }
        held = std::make_unique<RegistrationShare>(job.pairs, indices, std::move(factors),
                                                   job.T_world_frame, job.options);
        answer = encode_held(*held, time.elapsed_s(), scans_read(*store), peak_rss_bytes());
      }
    } catch (const std::bad_alloc&) {
      answer = encode_failure("out of memory");
    } catch (const std::exception& e) {
      answer = encode_failure(e.what());
    }
    send_answer(answer);
  }
#else
  (void)threads;
  return 1;
#endif
}

void MpiMapJob::note_peak_rss(std::size_t rank, std::uint64_t bytes) {
  peak_rss_bytes_per_rank_.resize(static_cast<std::size_t>(size_), 0);
  peak_rss_bytes_per_rank_[rank] = std::max(peak_rss_bytes_per_rank_[rank], bytes);
}

void MpiMapJob::count_sent(std::size_t bytes) {
  bytes_sent_per_rank_.resize(static_cast<std::size_t>(size_), 0);
  bytes_sent_per_rank_[0] += bytes;
}

void MpiMapJob::check_shares(std::size_t shares) const {
  if (shares != static_cast<std::size_t>(size_)) {
    throw Error("the job from rank 0 has " + std::to_string(shares) + " shares for " +
                std::to_string(size_) + " ranks");
  }
}

void check_mpi_applicable(const std::string& method, ResidualSampling sampling) {
  if (method != "gre")
    throw UsageError("--method " + method + " runs in one process; under mpirun use --method gre");
  if (sampling != ResidualSampling::kExact && sampling != ResidualSampling::kLossless) {
    throw UsageError(std::string("--sampling ") + to_string(sampling) +
                     " runs in one process; under mpirun use --sampling exact or lossless (a "
                     "few KB per factor to gather)");
  }
}

void MpiMapJob::attach(MpiFrameSource source, std::shared_ptr<FrameStore> frames,
                       MappingOptions* options, bool solver_only) {
  source_ = std::move(source);
  solver_only_ = solver_only;
  store_ = std::move(frames);  // rank 0's own share
  options->hold_factors =
      [this](std::span<const FramePair> pairs, std::span<const Eigen::Isometry3d> T_world_start,
             std::span<const std::size_t> order, const GlobalRegistrationOptions& gre) {
        return hold(pairs, T_world_start, order, gre);
      };
  const int threads = std::max(1, options->num_threads);  // rank 0's, as the stages would use
  options->loop_stages.validate = [this, threads](std::span<const LoopCandidate> candidates,
                                                  std::span<const Eigen::Isometry3d> T_world_guess,
                                                  const LoopClosureOptions& loops) {
    LoopWork work;
    work.kind = LoopWork::Kind::kValidate;
    work.max_correspondence_distance = loops.max_correspondence_distance;
    work.min_inlier_fraction = loops.min_inlier_fraction;
    work.max_drift_fraction = loops.max_drift_fraction;
    std::vector<FramePair> pairs;
    for (const LoopCandidate& candidate : candidates) {
      pairs.push_back(candidate.pair);
      work.descriptor_distance.push_back(candidate.descriptor_distance);
      work.yaw.push_back(candidate.yaw);
    }
    std::vector<LoopCheck> checks(candidates.size());
    for (std::size_t k = 0; k < candidates.size(); ++k) checks[k].candidate = candidates[k];
    share_loop_work(work, pairs, T_world_guess, threads, &checks, nullptr, nullptr);
    return checks;
  };
  options->loop_stages.register_consecutive =
      [this, threads](std::span<const FramePair> pairs, std::span<const Eigen::Isometry3d> T_world,
                      const AlignSettings& settings) {
        LoopWork work;
        work.kind = LoopWork::Kind::kRegister;
        work.settings = settings;
        std::vector<PairRegistration> registrations(pairs.size());
        share_loop_work(work, pairs, T_world, threads, nullptr, &registrations, nullptr);
        return registrations;
      };
  options->loop_stages.describe = [this, threads](std::size_t count,
                                                  const ScanContextOptions& descriptor) {
    LoopWork work;
    work.kind = LoopWork::Kind::kDescribe;
    work.descriptor = descriptor;
    std::vector<FramePair> items;  // item k: frame k
    for (std::size_t k = 0; k < count; ++k)
      items.push_back(FramePair{static_cast<int>(k), static_cast<int>(k), 0.0});
    std::vector<ScanContext> descriptors(count);
    share_loop_work(work, items, {}, threads, nullptr, nullptr, &descriptors);
    return descriptors;
  };
  options->measure_overlaps =
      [this](std::span<FramePair> pairs, std::span<const Eigen::Isometry3d> T_world_frame,
             const DenseGraphOptions& graph,
             const std::function<void(std::size_t, std::size_t)>& progress) {
        measure(pairs, T_world_frame, graph, progress);
      };
}

std::vector<std::vector<std::byte>> MpiMapJob::collect_answers(const std::string& own_failure) {
  std::vector<std::vector<std::byte>> answers(static_cast<std::size_t>(size_));
#if CARAT_WITH_MPI
  for (int r = 1; r < size_; ++r) answers[static_cast<std::size_t>(r)] = receive_answer(r);
#endif
  const auto failed = [&](int r, const std::string& message) {
    return Error("rank " + std::to_string(r) + " of " + std::to_string(size_) + ": " + message);
  };
  bytes_sent_per_rank_.resize(static_cast<std::size_t>(size_), 0);
  for (int r = 1; r < size_; ++r)
    bytes_sent_per_rank_[static_cast<std::size_t>(r)] +=
        answers[static_cast<std::size_t>(r)].size();
  if (!own_failure.empty()) throw failed(0, own_failure);
  for (int r = 1; r < size_; ++r) {
    const std::vector<std::byte>& bytes = answers[static_cast<std::size_t>(r)];
    bytes_gathered_ += bytes.size();
    const std::string message = answer_failure(bytes, "the answer of rank " + std::to_string(r));
    if (!message.empty()) throw failed(r, message);
  }
  return answers;
}

void MpiMapJob::share_loop_work(const LoopWork& work, std::span<const FramePair> pairs,
                                std::span<const Eigen::Isometry3d> T_world_frame, int threads,
                                std::vector<LoopCheck>* checks,
                                std::vector<PairRegistration>* registrations,
                                std::vector<ScanContext>* descriptors) {
#if CARAT_WITH_MPI
  std::uint64_t command = kLoops;
  // Contiguous stretches in index order: candidates come by their newer frame and consecutive
  // pairs by frame, so each rank reads about its part of the drive (and the loops' older frames).
  std::vector<std::size_t> order(pairs.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  const std::vector<std::vector<std::size_t>> shares = split_order(order, size_);
  std::vector<std::byte> payload = encode_loop_job(source_, work, pairs, T_world_frame, shares);
  count_sent(payload.size());
  broadcast(&command, &payload);
  LoopJob own;  // rank 0's share, as the others read theirs
  own.options = work;
  own.pairs.assign(pairs.begin(), pairs.end());
  own.T_world_frame.assign(T_world_frame.begin(), T_world_frame.end());
  std::string own_failure;
  const Stopwatch own_time;
  std::vector<std::byte> own_answer;
  try {
    own_answer = do_loop_share(*store_, own, shares[0], threads, own_time);
  } catch (const std::bad_alloc&) {
    own_failure = "out of memory";
  } catch (const std::exception& e) {
    own_failure = e.what();
  }
  loop_pairs_per_rank_.resize(static_cast<std::size_t>(size_), 0);
  loop_s_per_rank_.resize(static_cast<std::size_t>(size_), 0.0);
  std::vector<std::vector<std::byte>> answers = collect_answers(own_failure);
  answers[0] = std::move(own_answer);
  frames_read_per_rank_.resize(static_cast<std::size_t>(size_), 0);
  point_reads_per_rank_.resize(static_cast<std::size_t>(size_), 0);
  for (int r = 0; r < size_; ++r) {
    const auto rank = static_cast<std::size_t>(r);
    const std::string what = "the answer of rank " + std::to_string(r);
    const WorkAnswer answer =
        checks        ? read_loop_checks(answers[rank], what, shares[rank], checks)
        : descriptors ? read_descriptors(answers[rank], what, shares[rank], descriptors)
                      : read_registrations(answers[rank], what, shares[rank], registrations);
    loop_pairs_per_rank_[rank] += shares[rank].size();
    loop_s_per_rank_[rank] += answer.seconds;
    frames_read_per_rank_[rank] = answer.frames_read;
    point_reads_per_rank_[rank] = answer.point_reads;
    if (r > 0) note_peak_rss(rank, answer.peak_rss_bytes);
  }
#else
  (void)work;
  (void)pairs;
  (void)T_world_frame;
  (void)threads;
  (void)checks;
  (void)registrations;
  (void)descriptors;
#endif
}

void MpiMapJob::measure(std::span<FramePair> pairs,
                        std::span<const Eigen::Isometry3d> T_world_frame,
                        const DenseGraphOptions& options,
                        const std::function<void(std::size_t, std::size_t)>& progress) {
#if CARAT_WITH_MPI
  std::uint64_t command = kOverlaps;
  const std::vector<std::vector<std::size_t>> shares =
      split_order(locality_order(pairs, T_world_frame), size_);
  std::vector<std::byte> payload =
      encode_overlap_job(source_, options, pairs, T_world_frame, shares);
  count_sent(payload.size());
  broadcast(&command, &payload);
  std::string own_failure;
  const Stopwatch own_time;
  try {
    std::vector<FramePair> share;
    for (const std::size_t k : shares[0]) share.push_back(pairs[k]);
    if (!share.empty()) measure_overlaps(*store_, T_world_frame, share, options, progress);
    for (std::size_t q = 0; q < share.size(); ++q) pairs[shares[0][q]].overlap = share[q].overlap;
  } catch (const std::bad_alloc&) {
    own_failure = "out of memory";
  } catch (const std::exception& e) {
    own_failure = e.what();
  }
  overlap_s_per_rank_.assign(static_cast<std::size_t>(size_), 0.0);
  overlap_s_per_rank_[0] = own_time.elapsed_s();
  pairs_measured_per_rank_.assign(static_cast<std::size_t>(size_), 0);
  pairs_measured_per_rank_[0] = shares[0].size();
  frames_read_per_rank_.assign(static_cast<std::size_t>(size_), 0);
  point_reads_per_rank_.assign(static_cast<std::size_t>(size_), 0);
  const ScanReads own_reads = scans_read(*store_);
  frames_read_per_rank_[0] = own_reads.frames;
  point_reads_per_rank_[0] = own_reads.points;
  const std::vector<std::vector<std::byte>> answers = collect_answers(own_failure);
  std::vector<FramePair> measured(pairs.begin(), pairs.end());
  for (int r = 1; r < size_; ++r) {
    const auto rank = static_cast<std::size_t>(r);
    const WorkAnswer answer = read_overlap_answer(
        answers[rank], "the answer of rank " + std::to_string(r), shares[rank], &measured);
    overlap_s_per_rank_[rank] = answer.seconds;
    frames_read_per_rank_[rank] = answer.frames_read;
    point_reads_per_rank_[rank] = answer.point_reads;
    note_peak_rss(rank, answer.peak_rss_bytes);
    pairs_measured_per_rank_[rank] = shares[rank].size();
  }
  std::copy(measured.begin(), measured.end(), pairs.begin());
#else
  (void)pairs;
  (void)T_world_frame;
  (void)options;
  (void)progress;
#endif
}

/// Rank 0's view of a round's factors held over the ranks: the solve's block source.
class MpiMapJob::Held final : public HeldRegistrationFactors {
 public:
  Held(MpiMapJob* job, std::vector<VariableId> variables, RegistrationFactorStats stats,
       std::vector<std::size_t> correspondence_bytes, std::vector<std::size_t> residual_bytes)
      : job_(job),
        variables_(std::move(variables)),
        stats_(stats),
        correspondence_bytes_(std::move(correspondence_bytes)),
        residual_bytes_(std::move(residual_bytes)) {}
  std::size_t num_blocks() const override { return variables_.size() / 2; }
  std::span<const VariableId> variables(std::size_t k) const override {
    return std::span<const VariableId>(variables_).subspan(2 * k, 2);
  }
  void linearize(std::span<const double> values, const BlockRecordSink& sink) override {
    job_->stream(kLinearize, values, sink);
  }
  void costs(std::span<const double> values, const BlockRecordSink& sink) override {
    job_->stream(kCosts, values, sink);
  }
  std::size_t num_residual_rows() const override { return stats_.num_rows; }
  RegistrationFactorStats stats() const override { return stats_; }
  std::vector<std::size_t> correspondence_bytes() const override { return correspondence_bytes_; }
  std::vector<std::size_t> residual_bytes() const override { return residual_bytes_; }
  std::vector<double> factor_costs(std::span<const double> values) override {
    return job_->factor_costs(values, correspondence_bytes_.size());
  }

 private:
  MpiMapJob* job_;
  std::vector<VariableId> variables_;  // two a block: target, source
  RegistrationFactorStats stats_;
  std::vector<std::size_t> correspondence_bytes_;  // per pair
  std::vector<std::size_t> residual_bytes_;        // per pair
};

std::shared_ptr<HeldRegistrationFactors> MpiMapJob::hold(
    std::span<const FramePair> pairs, std::span<const Eigen::Isometry3d> T_world_start,
    std::span<const std::size_t> order, const GlobalRegistrationOptions& options) {
  std::vector<std::size_t> correspondence_bytes(pairs.size()), residual_bytes(pairs.size());
  RegistrationFactorStats stats;
  std::vector<VariableId> variables;
#if CARAT_WITH_MPI
  const Stopwatch stage_time;
  std::uint64_t command = kBuild;
  shares_ = split_order(order, solver_only_ ? size_ - 1 : size_);
  if (solver_only_) shares_.insert(shares_.begin(), std::vector<std::size_t>{});
  std::vector<std::byte> payload = encode_job(source_, options, pairs, T_world_start, shares_);
  count_sent(payload.size());
  own_.reset();  // the last round's factors go before this round's are built
  broadcast(&command, &payload);
  // Rank 0's own share, while the others build theirs; its failure waits for their answers.
  std::string own_failure;
  const std::vector<std::size_t>& own = shares_[0];
  const Stopwatch own_time;
  try {
    std::vector<RegistrationFactor> built;
    if (!own.empty())
      built = build_registration_factors(*store_, pairs, own, T_world_start, options);
    own_ =
        std::make_unique<RegistrationShare>(pairs, own, std::move(built), T_world_start, options);
  } catch (const std::bad_alloc&) {
    own_failure = "out of memory";
  } catch (const std::exception& e) {
    own_failure = e.what();
  }
  ++rounds_;
  factors_per_rank_.assign(static_cast<std::size_t>(size_), 0);
  factors_per_rank_[0] = own.size();
  build_s_per_rank_.assign(static_cast<std::size_t>(size_), 0.0);
  build_s_per_rank_[0] = own_time.elapsed_s();
  frames_read_per_rank_.assign(static_cast<std::size_t>(size_), 0);
  point_reads_per_rank_.assign(static_cast<std::size_t>(size_), 0);
  const ScanReads own_reads =
      store_->resident() ? ScanReads{store_->size(), 0} : scans_read(*store_);
  frames_read_per_rank_[0] = own_reads.frames;
  point_reads_per_rank_[0] = own_reads.points;
  const std::vector<std::vector<std::byte>> answers = collect_answers(own_failure);
  const auto add = [&](const RegistrationFactorStats& share, std::span<const std::size_t> indices,
                       std::span<const std::size_t> full, std::span<const std::size_t> kept) {
    static_assert(field_count<RegistrationFactorStats>() == 8, "MpiMapJob::hold: add the field");
    stats.num_factors += share.num_factors;
    stats.num_correspondences += share.num_correspondences;
    stats.num_rows += share.num_rows;
    stats.correspondence_bytes += share.correspondence_bytes;
    stats.residual_bytes += share.residual_bytes;
    stats.correspondence_s += share.correspondence_s;
    stats.compression_s += share.compression_s;
    stats.minimum_s += share.minimum_s;
    for (std::size_t q = 0; q < indices.size(); ++q) {
      correspondence_bytes[indices[q]] = full[q];
      residual_bytes[indices[q]] = kept[q];
      variables.push_back(VariableId{pairs[indices[q]].target});
      variables.push_back(VariableId{pairs[indices[q]].source});
    }
  };
  add(own_->stats(), own, own_->correspondence_bytes(), own_->residual_bytes());
  for (int r = 1; r < size_; ++r) {
    const auto rank = static_cast<std::size_t>(r);
    HeldAnswer held;
    const WorkAnswer answer = read_held_answer(
        answers[rank], "the answer of rank " + std::to_string(r), shares_[rank].size(), &held);
    build_s_per_rank_[rank] = answer.seconds;
    frames_read_per_rank_[rank] = answer.frames_read;
    point_reads_per_rank_[rank] = answer.point_reads;
    note_peak_rss(rank, answer.peak_rss_bytes);
    factors_per_rank_[rank] = shares_[rank].size();
    add(held.stats, shares_[rank], held.correspondence_bytes, held.residual_bytes);
  }
  // The stage ran in parallel: its CPU times split its wall time, as in one process.
  const double cpu = stats.correspondence_s + stats.compression_s + stats.minimum_s;
  const double wall = stage_time.elapsed_s();
  if (cpu > 0.0) {
    stats.correspondence_s *= wall / cpu;
    stats.compression_s *= wall / cpu;
    stats.minimum_s *= wall / cpu;
  }
#else
  (void)T_world_start;
  (void)order;
  (void)options;
#endif
  return std::make_shared<Held>(this, std::move(variables), stats, std::move(correspondence_bytes),
                                std::move(residual_bytes));
}

void MpiMapJob::stream(std::uint64_t command, std::span<const double> values,
                       const BlockRecordSink& sink) {
#if CARAT_WITH_MPI
  std::vector<std::byte> payload = bytes_of(values);
  values_bytes_ = payload.size();
  count_sent(payload.size());
  broadcast(&command, &payload);
  const bool linearizing = command == kLinearize;
  ++(linearizing ? linearizations_ : cost_evaluations_);
  std::size_t stream_bytes = 0;
  // Every rank's stream is read to its end, whatever fails, so that the next command finds the
  // ranks waiting for it; the first failure is thrown after.
  std::exception_ptr sink_error;
  std::size_t offset = 0;  // the first block of the rank being read
  const auto pass = [&](std::size_t first, std::span<const double> records) {
    if (sink_error) return;
    try {
      sink(offset + first, records);
    } catch (...) {
      sink_error = std::current_exception();
    }
  };
  std::string own_failure;
  try {
    if (!own_) throw Error("holds no factors (no build job came first)");
    if (command == kLinearize) {
      own_->linearize(values, pass);
    } else {
      own_->costs(values, pass);
    }
  } catch (const std::bad_alloc&) {
    own_failure = "out of memory";
  } catch (const std::exception& e) {
    own_failure = e.what();
  }
  const auto failed = [&](int r, const std::string& message) {
    return Error("rank " + std::to_string(r) + " of " + std::to_string(size_) + ": " + message);
  };
  std::vector<std::string> failures(static_cast<std::size_t>(size_));
  failures[0] = own_failure;
  bytes_sent_per_rank_.resize(static_cast<std::size_t>(size_), 0);
  std::vector<double> records;
  for (int r = 1; r < size_; ++r) {
    const auto rank = static_cast<std::size_t>(r);
    offset += shares_[rank - 1].size();
    const std::string what = "the records of rank " + std::to_string(r);
    for (;;) {
      const std::vector<std::byte> bytes = receive_answer(r);
      stream_bytes += bytes.size();
      bytes_sent_per_rank_[rank] += bytes.size();
      std::size_t first = 0;
      try {
        if (!read_records(bytes, what, &first, &records)) {
          failures[rank] = answer_failure(bytes, what);
          break;
        }
      } catch (const std::exception& e) {
        // Garbled bytes: what follows cannot be trusted to end the stream, so stop here.
        throw failed(r, e.what());
      }
      if (failures[rank].empty()) pass(first, records);
    }
  }
  (linearizing ? linearization_bytes_ : cost_bytes_) = stream_bytes;
  for (int r = 0; r < size_; ++r) {
    if (!failures[static_cast<std::size_t>(r)].empty())
      throw failed(r, failures[static_cast<std::size_t>(r)]);
  }
  if (sink_error) std::rethrow_exception(sink_error);
#else
  (void)command;
  (void)values;
  (void)sink;
#endif
}

std::vector<double> MpiMapJob::factor_costs(std::span<const double> values, std::size_t pairs) {
  std::vector<double> out(pairs, 0.0);
#if CARAT_WITH_MPI
  std::uint64_t command = kFactorCosts;
  std::vector<std::byte> payload = bytes_of(values);
  count_sent(payload.size());
  broadcast(&command, &payload);
  std::string own_failure;
  std::vector<double> own;
  try {
    if (!own_) throw Error("holds no factors (no build job came first)");
    own = own_->factor_costs(values);
  } catch (const std::bad_alloc&) {
    own_failure = "out of memory";
  } catch (const std::exception& e) {
    own_failure = e.what();
  }
  const std::vector<std::vector<std::byte>> answers = collect_answers(own_failure);
  for (std::size_t q = 0; q < own.size(); ++q) out[shares_[0][q]] = own[q];
  for (int r = 1; r < size_; ++r) {
    const auto rank = static_cast<std::size_t>(r);
    std::vector<double> costs;
    const WorkAnswer answer = read_numbers(answers[rank], "the answer of rank " + std::to_string(r),
                                           shares_[rank].size(), &costs);
    note_peak_rss(rank, answer.peak_rss_bytes);
    for (std::size_t q = 0; q < costs.size(); ++q) out[shares_[rank][q]] = costs[q];
  }
#else
  (void)values;
#endif
  return out;
}

std::string MpiMapJob::summary_line() const {
  const auto joined = [](const auto& values, const char* format) {
    std::string out;
    for (const auto value : values) {
      char text[32];
      std::snprintf(text, sizeof(text), format, value);
      out += (out.empty() ? "" : " / ") + std::string(text);
    }
    return out;
  };
  return "  mpi: " + std::to_string(size_) + " ranks measured " +
         joined(pairs_measured_per_rank_, "%zu") + " candidate pairs in " +
         joined(overlap_s_per_rank_, "%.2f") + " s, built and hold " +
         joined(factors_per_rank_, "%zu") + " factors (" + joined(build_s_per_rank_, "%.2f") +
         " s) from " + joined(frames_read_per_rank_, "%zu") + " frames (and " +
         joined(point_reads_per_rank_, "%zu") + " frames' points alone); " +
         std::to_string(linearizations_) + " linearizations (" +
         format_bytes(static_cast<double>(linearization_bytes_)) + " of records each) and " +
         std::to_string(cost_evaluations_) + " cost evaluations over " + std::to_string(rounds_) +
         (rounds_ == 1 ? " round" : " rounds");
}

nlohmann::json MpiMapJob::report() const {
  std::vector<std::uint64_t> peak_rss = peak_rss_bytes_per_rank_;
  peak_rss.resize(static_cast<std::size_t>(size_), 0);
  peak_rss[0] = peak_rss_bytes();
  std::vector<std::size_t> sent = bytes_sent_per_rank_;
  sent.resize(static_cast<std::size_t>(size_), 0);
  return {{"ranks", size_},
          {"peak_rss_bytes_per_rank", peak_rss},
          {"bytes_sent_per_rank", sent},
          {"rounds", rounds_},
          {"bytes_gathered", bytes_gathered_},
          {"loop_pairs_per_rank", loop_pairs_per_rank_},
          {"loop_s_per_rank", loop_s_per_rank_},
          {"pairs_measured_per_rank", pairs_measured_per_rank_},
          {"overlap_s_per_rank", overlap_s_per_rank_},
          {"factors_per_rank", factors_per_rank_},
          {"factors_held_per_rank", factors_per_rank_},
          {"linearizations", linearizations_},
          {"bytes_per_linearization", linearization_bytes_},
          {"cost_evaluations", cost_evaluations_},
          {"bytes_per_cost_evaluation", cost_bytes_},
          {"pose_bytes_per_linearization", values_bytes_},
          {"build_s_per_rank", build_s_per_rank_},
          {"frames_read_per_rank", frames_read_per_rank_},
          {"point_reads_per_rank", point_reads_per_rank_}};
}

}  // namespace carat::cli
