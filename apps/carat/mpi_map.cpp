#include "mpi_map.hpp"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <new>
#include <string>
#include <thread>
#include <utility>

#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/registration/dense_graph.hpp"
#include "carat/registration/frame_store.hpp"
#include "cli_support.hpp"
#include "mpi_launch.hpp"
#include "mpi_messages.hpp"

#if CARAT_WITH_MPI
#include <mpi.h>
#endif

namespace carat::cli {
namespace {

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

enum Command : std::uint64_t { kStop = 0, kBuild = 1, kOverlaps = 2 };
constexpr int kAnswerTag = 7;
constexpr std::size_t kChunk = std::size_t{1} << 30;  // MPI counts are int

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
  for (;;) {
    std::uint64_t command = kStop;
    std::vector<std::byte> payload;
    broadcast(&command, &payload);
    if (command != kBuild && command != kOverlaps) return 0;
    std::vector<std::byte> answer;
    try {
      // Each share's time from where rank 0's own starts: after the job is read.
      if (command == kOverlaps) {
        OverlapJob job = decode_overlap_job(payload);
        job.options.num_threads = threads;
        if (!store) store = frames_from(job.source);
        check_shares(job.shares.size());
        const Stopwatch time;
        std::vector<FramePair> share;
        for (const std::size_t k : job.shares[static_cast<std::size_t>(rank_)])
          share.push_back(job.pairs[k]);
        if (!share.empty()) measure_overlaps(*store, job.T_world_frame, share, job.options);
        answer = encode_overlaps(share, time.elapsed_s(), store->stats().loads, peak_rss_bytes());
      } else {
        BuildJob job = decode_job(payload);
        job.options.num_threads = threads;
        if (!store) store = frames_from(job.source);
        check_shares(job.shares.size());
        const Stopwatch time;
        const std::vector<std::size_t>& indices = job.shares[static_cast<std::size_t>(rank_)];
        std::vector<RegistrationFactor> factors;
        if (!indices.empty()) {
          factors = build_registration_factors(*store, job.pairs, indices, job.T_world_frame,
                                               job.options);
        }
        answer = encode_factors(indices, factors, time.elapsed_s(), store->stats().loads,
                                peak_rss_bytes());
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
                       MappingOptions* options) {
  source_ = std::move(source);
  store_ = std::move(frames);  // rank 0's own share
  options->build_factors =
      [this](std::span<const FramePair> pairs, std::span<const Eigen::Isometry3d> T_world_frame,
             const GlobalRegistrationOptions& gre) { return build(pairs, T_world_frame, gre); };
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

void MpiMapJob::measure(std::span<FramePair> pairs,
                        std::span<const Eigen::Isometry3d> T_world_frame,
                        const DenseGraphOptions& options,
                        const std::function<void(std::size_t, std::size_t)>& progress) {
#if CARAT_WITH_MPI
  std::uint64_t command = kOverlaps;
  const std::vector<std::vector<std::size_t>> shares = split_pairs(pairs, T_world_frame, size_);
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
  frames_read_per_rank_[0] = store_->stats().loads;
  const std::vector<std::vector<std::byte>> answers = collect_answers(own_failure);
  std::vector<FramePair> measured(pairs.begin(), pairs.end());
  for (int r = 1; r < size_; ++r) {
    const auto rank = static_cast<std::size_t>(r);
    const WorkAnswer answer = read_overlap_answer(
        answers[rank], "the answer of rank " + std::to_string(r), shares[rank], &measured);
    overlap_s_per_rank_[rank] = answer.seconds;
    frames_read_per_rank_[rank] = answer.frames_read;
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

std::vector<RegistrationFactor> MpiMapJob::build(std::span<const FramePair> pairs,
                                                 std::span<const Eigen::Isometry3d> T_world_frame,
                                                 const GlobalRegistrationOptions& options) {
  std::vector<RegistrationFactor> out(pairs.size());
#if CARAT_WITH_MPI
  std::uint64_t command = kBuild;
  // The shares stay those of the first round, so that each rank keeps the frames it read.
  if (shares_.empty() || shares_pairs_ != pairs.size())
    shares_ = split_pairs(pairs, T_world_frame, size_);
  shares_pairs_ = pairs.size();
  std::vector<std::byte> payload = encode_job(source_, options, pairs, T_world_frame, shares_);
  count_sent(payload.size());
  broadcast(&command, &payload);
  // Rank 0's own share, while the others build theirs; its failure waits for their answers.
  std::string own_failure;
  const std::vector<std::size_t>& own = shares_[0];
  const Stopwatch own_time;
  try {
    if (!own.empty()) {
      std::vector<RegistrationFactor> built =
          build_registration_factors(*store_, pairs, own, T_world_frame, options);
      for (std::size_t p = 0; p < own.size(); ++p) out[own[p]] = std::move(built[p]);
    }
  } catch (const std::bad_alloc&) {
    own_failure = "out of memory";
  } catch (const std::exception& e) {
    own_failure = e.what();
  }
  const double own_s = own_time.elapsed_s();
  ++rounds_;
  factors_per_rank_.assign(static_cast<std::size_t>(size_), 0);
  factors_per_rank_[0] = own.size();
  build_s_per_rank_.assign(static_cast<std::size_t>(size_), 0.0);
  build_s_per_rank_[0] = own_s;
  frames_read_per_rank_.assign(static_cast<std::size_t>(size_), 0);
  frames_read_per_rank_[0] = store_->resident() ? store_->size() : store_->stats().loads;
  const std::vector<std::vector<std::byte>> answers = collect_answers(own_failure);
  for (int r = 1; r < size_; ++r) {
    const auto rank = static_cast<std::size_t>(r);
    const WorkAnswer answer = read_factor_answer(
        answers[rank], "the answer of rank " + std::to_string(r), shares_[rank], &out);
    build_s_per_rank_[rank] = answer.seconds;
    frames_read_per_rank_[rank] = answer.frames_read;
    note_peak_rss(rank, answer.peak_rss_bytes);
    factors_per_rank_[rank] = shares_[rank].size();
  }
#else
  (void)pairs;
  (void)T_world_frame;
  (void)options;
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
         joined(overlap_s_per_rank_, "%.2f") + " s, built " + joined(factors_per_rank_, "%zu") +
         " factors in " + joined(build_s_per_rank_, "%.2f") + " s from " +
         joined(frames_read_per_rank_, "%zu") + " frames; " +
         format_bytes(static_cast<double>(bytes_gathered_)) + " gathered (the overlaps and " +
         std::to_string(rounds_) + (rounds_ == 1 ? " round" : " rounds") + " of factors)";
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
          {"pairs_measured_per_rank", pairs_measured_per_rank_},
          {"overlap_s_per_rank", overlap_s_per_rank_},
          {"factors_per_rank", factors_per_rank_},
          {"build_s_per_rank", build_s_per_rank_},
          {"frames_read_per_rank", frames_read_per_rank_}};
}

}  // namespace carat::cli
