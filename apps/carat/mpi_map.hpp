#pragma once

// `mpirun -np N carat map ...`: global registration with the factors built on N processes. Every
// rank runs the same command; rank 0 reads the frames, finds the dense graph and, each round,
// sends the pairs and start poses to the other ranks, which build and compress their share of
// the factors (a stretch of the pairs in locality order, one part of the map) from the frames
// those pairs need (read from the same --frames folder: a shared filesystem) and send them back
// as bytes. Rank 0 builds its own share, assembles, solves
// and writes the result, so the output is the one a single process writes, bit for bit.

#include <Eigen/Geometry>
#include <cstddef>
#include <memory>
#include <nlohmann/json.hpp>
#include <span>
#include <string>
#include <vector>

#include "carat/registration/dense_graph.hpp"
#include "carat/registration/frame.hpp"
#include "carat/registration/frame_store.hpp"
#include "carat/registration/global_registration.hpp"
#include "carat/registration/io/kitti_io.hpp"
#include "carat/registration/io/scan_folder.hpp"
#include "carat/registration/mapping.hpp"
#include "carat/registration/scan_opening.hpp"
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

  /// Rank 0: makes the GRE of `options` build its factors over the ranks: rank 0 from `frames`,
  /// the others from `source`. The job and `frames` must outlive the options' use.
  void attach(MpiFrameSource source, std::shared_ptr<FrameStore> frames, MappingOptions* options);
  /// Rank 0: one round's factors of every pair, parallel to the pairs, built over the ranks at
  /// T_world_frame. Throws carat::Error "rank r of N: ..." with the message of the lowest rank
  /// that failed, after every rank has answered.
  std::vector<RegistrationFactor> build(std::span<const FramePair> pairs,
                                        std::span<const Eigen::Isometry3d> T_world_frame,
                                        const GlobalRegistrationOptions& options);
  /// Rank 0: ranks, rounds, bytes gathered, and per rank the factors built, their build time
  /// and the frames read, for the JSON report.
  nlohmann::json report() const;
  /// Rank 0: the same as one line of the text report.
  std::string summary_line() const;

 private:
  MpiMapJob(int rank, int size) : rank_(rank), size_(size) {}

  int rank_ = 0;
  int size_ = 1;
  MpiFrameSource source_;
  std::shared_ptr<FrameStore> store_;             // rank 0's frames
  std::vector<std::vector<std::size_t>> shares_;  // per rank: the pairs it builds
  std::size_t shares_pairs_ = 0;                  // the pair count they were made for
  int rounds_ = 0;
  std::size_t bytes_gathered_ = 0;
  std::vector<std::size_t> factors_per_rank_;      // the last round's
  std::vector<double> build_s_per_rank_;           // the last round's wall time of each share
  std::vector<std::size_t> frames_read_per_rank_;  // frames each rank has read so far
};

}  // namespace carat::cli
