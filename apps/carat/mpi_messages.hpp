#pragma once

// The messages of `carat map` under mpirun, as bytes (what travels; mpi_map.cpp moves them):
// rank 0's loop jobs (the loop step's validations and consecutive registrations), overlap job
// (the dense graph's candidates) and build job each round, and each rank's answer (its checks,
// registrations, overlaps or what it holds, or its error); then, every linearization and cost
// evaluation of the solve, each rank's records as a stream of runs.

#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "carat/base/byte_stream.hpp"
#include "carat/registration/dense_graph.hpp"
#include "carat/registration/global_registration.hpp"
#include "carat/registration/held_factors.hpp"
#include "carat/registration/io/scan_folder.hpp"
#include "carat/registration/loop_closure.hpp"
#include "carat/registration/pair_registration.hpp"
#include "carat/registration/scan_opening.hpp"

namespace carat::cli {

/// What every rank needs to open the frames as rank 0 did (open_scans(); each rank reads on
/// demand under scans.max_bytes, 0: no cap, with one thread per frame).
struct MpiFrameSource {
  std::vector<ScanFile> files;  // the frames, in scan order
  OpenScansOptions scans;       // how they are read, checked and preprocessed
  /// Each file's size in bytes as rank 0 sees it (kUnknownSize where it could not tell), so that
  /// a rank that sees other files under the same paths fails instead of mapping other frames.
  std::vector<std::uint64_t> file_sizes;
};

/// A file size rank 0 could not read.
inline constexpr std::uint64_t kUnknownSize = ~std::uint64_t{0};

/// The sizes of `files` for MpiFrameSource::file_sizes.
std::vector<std::uint64_t> file_sizes(const std::vector<ScanFile>& files);

/// Throws carat::Error naming the first file whose size here differs from rank 0's ("DIR/x.bin:
/// 100 bytes on this rank but 1968 bytes on rank 0; every rank must read the same files").
void check_same_files(const MpiFrameSource& source);

/// What rank 0 sends every round: how to read the frames, how to build, what, and where.
struct BuildJob {
  MpiFrameSource source;
  GlobalRegistrationOptions options;
  std::vector<FramePair> pairs;
  std::vector<Eigen::Isometry3d> T_world_frame;
  std::vector<std::vector<std::size_t>> shares;  // per rank: the pairs it builds
};

/// What rank 0 sends to find the dense graph: how to read the frames, the overlap test's
/// settings, the candidate pairs, the poses, and the pairs each rank measures.
struct OverlapJob {
  MpiFrameSource source;
  DenseGraphOptions options;
  std::vector<FramePair> pairs;
  std::vector<Eigen::Isometry3d> T_world_frame;
  std::vector<std::vector<std::size_t>> shares;  // per rank: the pairs it measures
};

/// The loop step's GICP that rank 0 shares out: the validation of loop candidates (the pairs
/// with their descriptors' distance and yaw) or the registration of pairs.
struct LoopWork {
  /// What the ranks do with the items (the job's pairs).
  enum class Kind : std::uint8_t {
    kValidate = 0,  // validate_loop_candidates() of the candidates
    kRegister = 1,  // register_pairs() of the pairs
    kDescribe = 2,  // make_scan_context() of each item's target frame
  };
  Kind kind = Kind::kValidate;
  double max_correspondence_distance = 1.0;  // LoopClosureOptions: what the validation reads
  double min_inlier_fraction = 0.8;
  double max_drift_fraction = 0.1;
  AlignSettings settings;                   // register_pairs()'s
  ScanContextOptions descriptor;            // make_scan_context()'s
  std::vector<double> descriptor_distance;  // per candidate
  std::vector<double> yaw;                  // per candidate
};

/// What rank 0 sends for the loop step: how to read the frames, the work, the candidates' (or
/// the pairs') frames, the guess, and what each rank does (contiguous stretches).
struct LoopJob {
  MpiFrameSource source;
  LoopWork options;
  std::vector<FramePair> pairs;
  std::vector<Eigen::Isometry3d> T_world_frame;
  std::vector<std::vector<std::size_t>> shares;  // per rank: the candidates (pairs) it does
};

/// Appends every field of `work`.
void write_options(ByteWriter& out, const LoopWork& work);

/// The loop job as bytes.
std::vector<std::byte> encode_loop_job(const MpiFrameSource& source, const LoopWork& work,
                                       std::span<const FramePair> pairs,
                                       std::span<const Eigen::Isometry3d> T_world_frame,
                                       const std::vector<std::vector<std::size_t>>& shares);

/// The loop job from its bytes; throws carat::Error ("the loop job from rank 0: garbled: ...")
/// for bytes encode_loop_job() does not write.
LoopJob decode_loop_job(std::span<const std::byte> bytes);

/// The overlap job as bytes.
std::vector<std::byte> encode_overlap_job(const MpiFrameSource& source,
                                          const DenseGraphOptions& options,
                                          std::span<const FramePair> pairs,
                                          std::span<const Eigen::Isometry3d> T_world_frame,
                                          const std::vector<std::vector<std::size_t>>& shares);

/// The overlap job from its bytes; throws carat::Error ("the overlap job from rank 0: garbled:
/// ...") for bytes encode_overlap_job() does not write.
OverlapJob decode_overlap_job(std::span<const std::byte> bytes);

/// A round's job as bytes.
std::vector<std::byte> encode_job(const MpiFrameSource& source,
                                  const GlobalRegistrationOptions& options,
                                  std::span<const FramePair> pairs,
                                  std::span<const Eigen::Isometry3d> T_world_frame,
                                  const std::vector<std::vector<std::size_t>>& shares);

/// The job from its bytes; throws carat::Error ("the job from rank 0: garbled: ...") for bytes
/// encode_job() does not write.
BuildJob decode_job(std::span<const std::byte> bytes);

/// The blocks split over `ranks` ranks: contiguous stretches of `order` (block_order() at the
/// first round's poses), as equal in count as can be, so that each rank reads only the frames
/// of one part of the map (and a few loop partners), and rank r's blocks follow rank r - 1's.
std::vector<std::vector<std::size_t>> split_order(std::span<const std::size_t> order, int ranks);

/// A rank's answer when it failed: the message.
std::vector<std::byte> encode_failure(const std::string& message);

/// The message of a failed answer, or empty for any other; `what` names the answer in errors.
std::string answer_failure(std::span<const std::byte> bytes, const std::string& what);

/// Scans a rank has read from disk so far.
struct ScanReads {
  std::size_t frames = 0;  // whole frames read and built (FrameStoreStats::loads)
  std::size_t points = 0;  // frames read for their points alone (FrameStoreStats::point_loads)
};

/// What an answer with work done said besides it.
struct WorkAnswer {
  double seconds = 0.0;              // the rank's wall time for its share
  std::size_t frames_read = 0;       // frames the rank has read and built so far
  std::size_t point_reads = 0;       // frames it has read for their points alone so far
  std::uint64_t peak_rss_bytes = 0;  // the rank's peak resident memory so far
};

/// A rank's answer to a build job: its build time (s), the frames it has read, its peak resident
/// memory (bytes), and of the factors it now holds their stats and per factor the bytes of its
/// full block and of its kept block.
std::vector<std::byte> encode_held(const RegistrationShare& share, double build_s, ScanReads reads,
                                   std::uint64_t peak_rss_bytes);

/// What an answer to a build job says of the held factors.
struct HeldAnswer {
  RegistrationFactorStats stats;                  // summed over the rank's factors (CPU times)
  std::vector<std::size_t> correspondence_bytes;  // per factor of the share
  std::vector<std::size_t> residual_bytes;        // per factor of the share
};

/// Reads an answer to a build job for a share of `count` factors into *held. Throws carat::Error
/// naming `what` for bytes that are not that answer.
WorkAnswer read_held_answer(std::span<const std::byte> bytes, const std::string& what,
                            std::size_t count, HeldAnswer* held);

/// One run of a rank's records (linearizations or costs) for its blocks from `first` on (in its
/// share), as one message of a stream that encode_done() or encode_failure() ends.
std::vector<std::byte> encode_records(std::size_t first, std::span<const double> records);

/// The end of a stream of records that went well.
std::vector<std::byte> encode_done();

/// Reads a message of a stream of records: true with the run's first block and its records, or
/// false for the stream's end (then answer_failure() says whether it failed). Throws
/// carat::Error naming `what` for other bytes.
bool read_records(std::span<const std::byte> bytes, const std::string& what, std::size_t* first,
                  std::vector<double>* records);

/// A rank's answer with one number per factor of its share (their costs per correspondence) and
/// its peak resident memory (bytes).
std::vector<std::byte> encode_numbers(std::span<const double> numbers,
                                      std::uint64_t peak_rss_bytes);

/// Reads encode_numbers()'s answer of `count` numbers into *numbers. Throws carat::Error naming
/// `what` for other bytes.
WorkAnswer read_numbers(std::span<const std::byte> bytes, const std::string& what,
                        std::size_t count, std::vector<double>* numbers);

/// A rank's answer to an overlap job: its time (s), the frames it has read, its peak resident
/// memory (bytes), and the overlap of each pair of its share, in the share's order.
std::vector<std::byte> encode_overlaps(std::span<const FramePair> pairs, double measure_s,
                                       ScanReads reads, std::uint64_t peak_rss_bytes);

/// Reads an answer with overlaps: the overlaps of `expected` (pair indices) into
/// (*pairs)[k].overlap. Throws carat::Error naming `what` for bytes that are not that answer or
/// an overlap outside [0, 1].
WorkAnswer read_overlap_answer(std::span<const std::byte> bytes, const std::string& what,
                               std::span<const std::size_t> expected,
                               std::vector<FramePair>* pairs);

/// A rank's answer to a loop job: its time (s), the frames it has read, its peak resident
/// memory (bytes), and its share's checks (validation) or registrations, in the share's order.
std::vector<std::byte> encode_loop_checks(std::span<const LoopCheck> checks, double seconds,
                                          ScanReads reads, std::uint64_t peak_rss_bytes);
/// The same for descriptors.
std::vector<std::byte> encode_descriptors(std::span<const ScanContext> descriptors, double seconds,
                                          ScanReads reads, std::uint64_t peak_rss_bytes);
/// The same for registrations.
std::vector<std::byte> encode_registrations(std::span<const PairRegistration> registrations,
                                            double seconds, ScanReads reads,
                                            std::uint64_t peak_rss_bytes);

/// Reads encode_loop_checks()'s answer into (*checks)[k] for k in `expected`. Throws
/// carat::Error naming `what` for bytes that are not that answer.
WorkAnswer read_loop_checks(std::span<const std::byte> bytes, const std::string& what,
                            std::span<const std::size_t> expected, std::vector<LoopCheck>* checks);
/// Reads encode_descriptors()'s answer into (*descriptors)[k] for k in `expected`; throws as
/// read_loop_checks().
WorkAnswer read_descriptors(std::span<const std::byte> bytes, const std::string& what,
                            std::span<const std::size_t> expected,
                            std::vector<ScanContext>* descriptors);
/// Reads encode_registrations()'s answer into (*registrations)[k] for k in `expected`; throws
/// as read_loop_checks().
WorkAnswer read_registrations(std::span<const std::byte> bytes, const std::string& what,
                              std::span<const std::size_t> expected,
                              std::vector<PairRegistration>* registrations);

}  // namespace carat::cli
