#pragma once

// `mpirun -np N carat map ...`: the dense graph and global registration's factors on N
// processes. Every rank runs the same command. Rank 0 lists the dense graph's candidate pairs and
// sends them with the start poses to the other ranks; each rank measures the overlaps of its
// share (a stretch of the pairs in locality order, one part of the map), and rank 0 keeps the
// pairs that overlap enough. Each round, every rank builds and compresses one stretch of the
// factors in block order (block_order()) and keeps them; every linearization and cost
// evaluation of the solve, rank 0 sends the poses and each rank streams back its factors'
// records (block_source.hpp), which rank 0 adds to the reduced system in block order. Every rank
// reads only the frames its shares need (from the same --frames folder: a shared filesystem).
// Rank 0 holds the poses, the reduced system and its own share, solves and writes the result:
// the output is the one a single process writes, bit for bit.

#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <span>
#include <string>
#include <vector>

#include "carat/registration/dense_graph.hpp"
#include "carat/registration/frame.hpp"
#include "carat/registration/frame_store.hpp"
#include "carat/registration/global_registration.hpp"
#include "carat/registration/held_factors.hpp"
#include "carat/registration/io/kitti_io.hpp"
#include "carat/registration/io/scan_folder.hpp"
#include "carat/registration/mapping.hpp"
#include "carat/registration/scan_opening.hpp"
#include "carat/solver/block_source.hpp"
#include "mpi_messages.hpp"

namespace carat::cli {

/// Refuses what the ranks cannot share: the PGO baselines and full or random sampling (whose
/// factors are not a few KB each); throws UsageError.
void check_mpi_applicable(const std::string& method, ResidualSampling sampling);

/// One process of an MPI job of carat map.
class MpiMapJob {
 public:
  /// The job this process is part of, or null when it was not started by mpirun with 2 or more
  /// ranks. Throws carat::Error when it was, but carat was built without MPI.
  static std::unique_ptr<MpiMapJob> start();
  /// Rank 0 tells the other ranks to stop (also when it fails); then MPI ends on every rank.
  ~MpiMapJob();
  MpiMapJob(const MpiMapJob&) = delete;
  MpiMapJob& operator=(const MpiMapJob&) = delete;

  /// This process's rank (0 solves and writes).
  int rank() const { return rank_; }
  /// Number of ranks.
  int size() const { return size_; }

  /// Ranks > 0: builds the factors rank 0 asks for with `threads` threads until it says stop;
  /// a failure is sent to rank 0 (which reports it) instead of factors. Returns the exit status.
  int serve(int threads);

  /// Rank 0: makes the dense graph of `options` measure its overlaps, and its GRE build and hold
  /// its factors, over the ranks: rank 0 from `frames`, the others from `source`; with
  /// `solver_only`, rank 0 builds and holds no factor (the other ranks share them). The job and
  /// `frames` must outlive the options' use.
  void attach(MpiFrameSource source, std::shared_ptr<FrameStore> frames, MappingOptions* options,
              bool solver_only = false);
  /// Rank 0: one round's factors of every pair, built at T_world_start and held over the ranks
  /// (rank r the r-th stretch of `order`; with solver_only, rank 0 none and rank r the r-th of
  /// N - 1), as the solve's block source. Throws carat::Error
  /// "rank r of N: ..." with the message of the lowest rank that failed, after every rank has
  /// answered.
  std::shared_ptr<HeldRegistrationFactors> hold(std::span<const FramePair> pairs,
                                                std::span<const Eigen::Isometry3d> T_world_start,
                                                std::span<const std::size_t> order,
                                                const GlobalRegistrationOptions& options);
  /// Rank 0: the overlap of every candidate pair at T_world_frame, measured over the ranks (each
  /// its share, as measure_overlaps(); `progress`, if set, follows rank 0's share). Throws
  /// carat::Error "rank r of N: ..." as hold().
  void measure(std::span<FramePair> pairs, std::span<const Eigen::Isometry3d> T_world_frame,
               const DenseGraphOptions& options,
               const std::function<void(std::size_t, std::size_t)>& progress = {});
  /// Rank 0: the loop step's work over the ranks (each a contiguous stretch of `pairs`): with
  /// `checks`, the validation of the candidates (whose pairs `pairs` are; the checks hold the
  /// candidates already) into it; with `descriptors`, the descriptor of each item's target frame
  /// into it; else the registrations of `pairs` into *registrations. Rank 0 does its share with
  /// `threads` threads. Throws carat::Error "rank r of N: ..." as hold().
  void share_loop_work(const LoopWork& work, std::span<const FramePair> pairs,
                       std::span<const Eigen::Isometry3d> T_world_frame, int threads,
                       std::vector<LoopCheck>* checks, std::vector<PairRegistration>* registrations,
                       std::vector<ScanContext>* descriptors);
  /// Rank 0: ranks, rounds, linearizations, bytes gathered, and per rank its peak resident
  /// memory, the bytes it sent (rank 0: the jobs and poses; the others: their answers and
  /// records), the pairs measured and their time, the factors built, held and their build time,
  /// and the frames read, for the JSON report.
  nlohmann::json report() const;
  /// Rank 0: the same as one line of the text report.
  std::string summary_line() const;

 private:
  MpiMapJob(int rank, int size) : rank_(rank), size_(size) {}
  /// Throws unless a job has one share per rank.
  void check_shares(std::size_t shares) const;
  /// Rank 0: counts `bytes` it sent (a job's payload).
  void count_sent(std::size_t bytes);
  /// Rank 0: keeps the largest peak resident memory a rank reported.
  void note_peak_rss(std::size_t rank, std::uint64_t bytes);
  /// Rank 0: sends `command` with `values` (the poses), passes its own share's records and then
  /// each rank's to `sink` as they arrive (blocks numbered in block order), and throws "rank r
  /// of N: ..." for the lowest rank that failed once every rank's stream has ended.
  void stream(std::uint64_t command, std::span<const double> values, const BlockRecordSink& sink);
  /// Rank 0: each factor's cost per correspondence at `values`, parallel to the pairs.
  std::vector<double> factor_costs(std::span<const double> values, std::size_t pairs);
  class Held;

  /// Rank 0: every other rank's answer (index r), after its own work failed with `own_failure`
  /// (empty: it did not); throws "rank r of N: ..." for the lowest rank that failed.
  std::vector<std::vector<std::byte>> collect_answers(const std::string& own_failure);

  int rank_ = 0;
  int size_ = 1;
  MpiFrameSource source_;
  std::shared_ptr<FrameStore> store_;             // rank 0's frames
  std::vector<std::vector<std::size_t>> shares_;  // per rank: the pairs it holds, in block order
  std::unique_ptr<RegistrationShare> own_;        // rank 0's held factors
  bool solver_only_ = false;                      // rank 0 holds none
  int rounds_ = 0;
  std::size_t linearizations_ = 0;       // of the solves (and covariances)
  std::size_t cost_evaluations_ = 0;     // of the solves' trial points
  std::size_t linearization_bytes_ = 0;  // what the other ranks sent rank 0 in the last one
  std::size_t cost_bytes_ = 0;           // the same of the last cost evaluation
  std::size_t values_bytes_ = 0;         // the poses rank 0 sends with each of them
  std::size_t bytes_gathered_ = 0;
  std::vector<std::size_t> factors_per_rank_;           // the last round's, built and held
  std::vector<double> build_s_per_rank_;                // the last round's wall time of each share
  std::vector<std::size_t> frames_read_per_rank_;       // frames each rank has read so far
  std::vector<std::size_t> point_reads_per_rank_;       // frames read for their points alone
  std::vector<std::size_t> loop_pairs_per_rank_;        // the loop step's GICP pairs done
  std::vector<double> loop_s_per_rank_;                 // their wall time
  std::vector<std::size_t> pairs_measured_per_rank_;    // the dense graph's candidates measured
  std::vector<double> overlap_s_per_rank_;              // wall time of each share of them
  std::vector<std::uint64_t> peak_rss_bytes_per_rank_;  // as the ranks last reported it
  std::vector<std::size_t> bytes_sent_per_rank_;        // rank 0: jobs; others: their answers
};

}  // namespace carat::cli
