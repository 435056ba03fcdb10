#include "mpi_messages.hpp"

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <system_error>
#include <utility>

#include "carat/base/byte_stream.hpp"
#include "carat/base/error.hpp"
#include "carat/base/field_count.hpp"
#include "carat/registration/option_serialization.hpp"

namespace carat::cli {

namespace {

/// The first byte of every answer.
enum AnswerKind : std::uint8_t { kFailed = 0, kWorkDone = 1, kRecords = 2, kStreamDone = 3 };

void write_source(ByteWriter& out, const MpiFrameSource& source) {
  out.put(static_cast<std::uint64_t>(source.files.size()));
  for (std::size_t k = 0; k < source.files.size(); ++k) {
    const ScanFile& file = source.files[k];
    out.put_string(file.path.string());
    out.put_string(file.name);
    out.put(static_cast<std::uint8_t>(file.bin_format));
    out.put(k < source.file_sizes.size() ? source.file_sizes[k] : kUnknownSize);
  }
  write_options(out, source.scans);
}

MpiFrameSource read_source(ByteReader& in) {
  MpiFrameSource source;
  const auto files = in.get<std::uint64_t>();
  if (files > in.remaining()) in.garbled("frame count");
  for (std::uint64_t k = 0; k < files; ++k) {
    ScanFile file;
    file.path = in.get_string();
    file.name = in.get_string();
    file.bin_format = static_cast<KittiFormat>(in.get<std::uint8_t>());
    source.files.push_back(std::move(file));
    source.file_sizes.push_back(in.get<std::uint64_t>());
  }
  source.scans = read_open_scans_options(in);
  return source;
}

/// The pairs, the poses and the shares.
void write_work(ByteWriter& out, std::span<const FramePair> pairs,
                std::span<const Eigen::Isometry3d> T_world_frame,
                const std::vector<std::vector<std::size_t>>& shares) {
  out.put(static_cast<std::uint64_t>(pairs.size()));
  out.put_array(pairs);
  out.put(static_cast<std::uint64_t>(T_world_frame.size()));
  for (const Eigen::Isometry3d& T : T_world_frame)
    out.put_array(std::span<const double>(T.matrix().data(), 16));
  out.put(static_cast<std::uint64_t>(shares.size()));
  for (const std::vector<std::size_t>& share : shares) {
    out.put(static_cast<std::uint64_t>(share.size()));
    for (const std::size_t k : share) out.put(static_cast<std::uint64_t>(k));
  }
}

void read_work(ByteReader& in, std::vector<FramePair>* pairs,
               std::vector<Eigen::Isometry3d>* T_world_frame,
               std::vector<std::vector<std::size_t>>* shares) {
  *pairs = in.get_array<FramePair>(static_cast<std::size_t>(in.get<std::uint64_t>()));
  const auto poses = in.get<std::uint64_t>();
  if (poses > in.remaining() / (16 * sizeof(double))) in.garbled("pose count");
  for (std::uint64_t k = 0; k < poses; ++k) {
    Eigen::Isometry3d T;
    const std::vector<double> m = in.get_array<double>(16);
    std::copy(m.begin(), m.end(), T.matrix().data());
    T_world_frame->push_back(T);
  }
  const auto ranks = in.get<std::uint64_t>();
  if (ranks > in.remaining() / sizeof(std::uint64_t)) in.garbled("rank count");
  for (std::uint64_t r = 0; r < ranks; ++r) {
    std::vector<std::size_t> share;
    for (const std::uint64_t k :
         in.get_array<std::uint64_t>(static_cast<std::size_t>(in.get<std::uint64_t>()))) {
      if (k >= pairs->size()) in.garbled("pair index " + std::to_string(k));
      share.push_back(static_cast<std::size_t>(k));
    }
    shares->push_back(std::move(share));
  }
}

/// An answer's start: success, the rank's time, scans read, peak memory and item count.
void write_answer_header(ByteWriter& out, double seconds, ScanReads reads,
                         std::uint64_t peak_rss_bytes, std::size_t items) {
  out.put(std::uint8_t{kWorkDone});
  out.put(seconds);
  out.put(static_cast<std::uint64_t>(reads.frames));
  out.put(static_cast<std::uint64_t>(reads.points));
  out.put(peak_rss_bytes);
  out.put(static_cast<std::uint64_t>(items));
}

/// Reads write_answer_header()'s fields; garbled unless the count is `items` (`name` says of
/// what).
WorkAnswer read_answer_header(ByteReader& in, std::size_t items, const char* name) {
  if (in.get<std::uint8_t>() != kWorkDone) in.garbled("answer kind");
  WorkAnswer answer;
  answer.seconds = in.get<double>();
  answer.frames_read = static_cast<std::size_t>(in.get<std::uint64_t>());
  answer.point_reads = static_cast<std::size_t>(in.get<std::uint64_t>());
  answer.peak_rss_bytes = in.get<std::uint64_t>();
  if (in.get<std::uint64_t>() != items) in.garbled(std::string(name) + " count");
  return answer;
}

/// An answer of one item per entry of a share: the header, then write(out, item) for each.
template <class Item, class Write>
std::vector<std::byte> encode_items(std::span<const Item> items, double seconds, ScanReads reads,
                                    std::uint64_t peak_rss_bytes, Write write) {
  std::vector<std::byte> bytes;
  ByteWriter out(bytes);
  write_answer_header(out, seconds, reads, peak_rss_bytes, items.size());
  for (const Item& item : items) write(out, item);
  return bytes;
}

/// Reads encode_items()'s answer for the share `expected`: read(in, k) for each of its indices
/// (`name` says of what, in errors).
template <class Read>
WorkAnswer read_items(std::span<const std::byte> bytes, const std::string& what,
                      std::span<const std::size_t> expected, const char* name, Read read) {
  ByteReader in(bytes, what);
  const WorkAnswer answer = read_answer_header(in, expected.size(), name);
  for (const std::size_t k : expected) read(in, k);
  in.expect_end();
  return answer;
}

/// A job: how to read the frames, the stage's settings, the pairs, the poses and the shares.
template <class Options>
std::vector<std::byte> encode_work_job(const MpiFrameSource& source, const Options& options,
                                       std::span<const FramePair> pairs,
                                       std::span<const Eigen::Isometry3d> T_world_frame,
                                       const std::vector<std::vector<std::size_t>>& shares) {
  std::vector<std::byte> bytes;
  ByteWriter out(bytes);
  write_source(out, source);
  write_options(out, options);
  write_work(out, pairs, T_world_frame, shares);
  return bytes;
}

/// What encode_work_job() wrote, its settings read by `read_options`; `what` names it in errors.
template <class Job, class ReadOptions>
Job decode_work_job(std::span<const std::byte> bytes, const char* what, ReadOptions read_options) {
  ByteReader in(bytes, what);
  Job job;
  job.source = read_source(in);
  job.options = read_options(in);
  read_work(in, &job.pairs, &job.T_world_frame, &job.shares);
  in.expect_end();
  return job;
}

/// Every field of a registration (its relative pose and Hessian bit for bit).
void write_registration(ByteWriter& out, const PairRegistration& r) {
  static_assert(field_count<PairRegistration>() == 9, "mpi_messages: write the new field");
  out.put(static_cast<std::int64_t>(r.pair.target));
  out.put(static_cast<std::int64_t>(r.pair.source));
  out.put(r.pair.overlap);
  out.put_array(std::span<const double>(r.T_target_source.matrix().data(), 16));
  out.put_array(std::span<const double>(r.H.data(), 36));
  out.put(r.error);
  out.put(static_cast<std::int64_t>(r.num_correspondences));
  out.put(static_cast<std::int64_t>(r.iterations));
  out.put(static_cast<std::uint8_t>(r.converged ? 1 : 0));
  out.put(static_cast<std::int64_t>(r.constrained_dof));
  out.put(r.align_s);
}

PairRegistration read_registration(ByteReader& in) {
  PairRegistration r;
  r.pair.target = static_cast<int>(in.get<std::int64_t>());
  r.pair.source = static_cast<int>(in.get<std::int64_t>());
  r.pair.overlap = in.get<double>();
  const std::vector<double> T = in.get_array<double>(16);
  std::copy(T.begin(), T.end(), r.T_target_source.matrix().data());
  const std::vector<double> H = in.get_array<double>(36);
  std::copy(H.begin(), H.end(), r.H.data());
  r.error = in.get<double>();
  r.num_correspondences = static_cast<int>(in.get<std::int64_t>());
  r.iterations = static_cast<int>(in.get<std::int64_t>());
  const auto converged = in.get<std::uint8_t>();
  if (converged > 1) in.garbled("converged flag");
  r.converged = converged == 1;
  r.constrained_dof = static_cast<int>(in.get<std::int64_t>());
  r.align_s = in.get<double>();
  return r;
}

LoopWork read_loop_work(ByteReader& in) {
  LoopWork work;
  const auto kind = in.get<std::uint8_t>();
  if (kind > static_cast<std::uint8_t>(LoopWork::Kind::kDescribe)) in.garbled("loop work kind");
  work.kind = static_cast<LoopWork::Kind>(kind);
  work.max_correspondence_distance = in.get<double>();
  work.min_inlier_fraction = in.get<double>();
  work.max_drift_fraction = in.get<double>();
  const auto method = in.get<std::uint8_t>();
  if (method > static_cast<std::uint8_t>(RegistrationMethod::kPointToPoint))
    in.garbled("registration method");
  work.settings.method = static_cast<RegistrationMethod>(method);
  work.settings.max_correspondence_distance = in.get<double>();
  work.settings.max_iterations = static_cast<int>(in.get<std::int64_t>());
  work.settings.translation_tolerance = in.get<double>();
  work.settings.rotation_tolerance = in.get<double>();
  work.settings.min_correspondences = static_cast<int>(in.get<std::int64_t>());
  work.settings.num_threads = static_cast<int>(in.get<std::int64_t>());
  work.descriptor.rings = static_cast<int>(in.get<std::int64_t>());
  work.descriptor.sectors = static_cast<int>(in.get<std::int64_t>());
  work.descriptor.max_range = in.get<double>();
  work.descriptor.height_offset = in.get<double>();
  work.descriptor.min_occupied_bins = static_cast<int>(in.get<std::int64_t>());
  const auto candidates = in.get<std::uint64_t>();
  if (candidates > in.remaining() / (2 * sizeof(double))) in.garbled("candidate count");
  work.descriptor_distance = in.get_array<double>(static_cast<std::size_t>(candidates));
  work.yaw = in.get_array<double>(static_cast<std::size_t>(candidates));
  return work;
}

}  // namespace

void write_options(ByteWriter& out, const LoopWork& work) {
  static_assert(field_count<AlignSettings>() == 7, "mpi_messages: write the new field");
  static_assert(field_count<ScanContextOptions>() == 5, "mpi_messages: write the new field");
  out.put(static_cast<std::uint8_t>(work.kind));
  out.put(work.max_correspondence_distance);
  out.put(work.min_inlier_fraction);
  out.put(work.max_drift_fraction);
  out.put(static_cast<std::uint8_t>(work.settings.method));
  out.put(work.settings.max_correspondence_distance);
  out.put(static_cast<std::int64_t>(work.settings.max_iterations));
  out.put(work.settings.translation_tolerance);
  out.put(work.settings.rotation_tolerance);
  out.put(static_cast<std::int64_t>(work.settings.min_correspondences));
  out.put(static_cast<std::int64_t>(work.settings.num_threads));
  out.put(static_cast<std::int64_t>(work.descriptor.rings));
  out.put(static_cast<std::int64_t>(work.descriptor.sectors));
  out.put(work.descriptor.max_range);
  out.put(work.descriptor.height_offset);
  out.put(static_cast<std::int64_t>(work.descriptor.min_occupied_bins));
  out.put(static_cast<std::uint64_t>(work.descriptor_distance.size()));
  out.put_array(std::span<const double>(work.descriptor_distance));
  out.put_array(std::span<const double>(work.yaw));
}

std::vector<std::byte> encode_loop_job(const MpiFrameSource& source, const LoopWork& work,
                                       std::span<const FramePair> pairs,
                                       std::span<const Eigen::Isometry3d> T_world_frame,
                                       const std::vector<std::vector<std::size_t>>& shares) {
  return encode_work_job(source, work, pairs, T_world_frame, shares);
}

LoopJob decode_loop_job(std::span<const std::byte> bytes) {
  LoopJob job = decode_work_job<LoopJob>(bytes, "the loop job from rank 0", read_loop_work);
  if (job.options.kind == LoopWork::Kind::kValidate &&
      (job.options.descriptor_distance.size() != job.pairs.size() ||
       job.options.yaw.size() != job.pairs.size())) {
    throw Error("the loop job from rank 0: garbled: " + std::to_string(job.options.yaw.size()) +
                " candidates' descriptors for " + std::to_string(job.pairs.size()) + " pairs");
  }
  return job;
}

std::vector<std::byte> encode_loop_checks(std::span<const LoopCheck> checks, double seconds,
                                          ScanReads reads, std::uint64_t peak_rss_bytes) {
  return encode_items(checks, seconds, reads, peak_rss_bytes,
                      [](ByteWriter& out, const LoopCheck& check) {
                        out.put(static_cast<std::uint8_t>(check.verdict));
                        out.put(check.inlier_fraction);
                        write_registration(out, check.registration);
                      });
}

std::vector<std::byte> encode_descriptors(std::span<const ScanContext> descriptors, double seconds,
                                          ScanReads reads, std::uint64_t peak_rss_bytes) {
  static_assert(field_count<ScanContext>() == 6, "mpi_messages: write the new field");
  return encode_items(descriptors, seconds, reads, peak_rss_bytes,
                      [](ByteWriter& out, const ScanContext& d) {
                        out.put(static_cast<std::int64_t>(d.rings));
                        out.put(static_cast<std::int64_t>(d.sectors));
                        out.put(static_cast<std::uint64_t>(d.bins.size()));
                        out.put_array(std::span<const float>(d.bins));
                        out.put(static_cast<std::uint64_t>(d.ring_key.size()));
                        out.put_array(std::span<const float>(d.ring_key));
                        out.put(static_cast<std::int64_t>(d.occupied_bins));
                        out.put(static_cast<std::uint8_t>(d.valid ? 1 : 0));
                      });
}

WorkAnswer read_descriptors(std::span<const std::byte> bytes, const std::string& what,
                            std::span<const std::size_t> expected,
                            std::vector<ScanContext>* descriptors) {
  return read_items(bytes, what, expected, "descriptor", [&](ByteReader& in, std::size_t k) {
    ScanContext& d = (*descriptors)[k];
    d.rings = static_cast<int>(in.get<std::int64_t>());
    d.sectors = static_cast<int>(in.get<std::int64_t>());
    const auto bins = in.get<std::uint64_t>();
    if (bins > in.remaining() / sizeof(float)) in.garbled("bin count");
    d.bins = in.get_array<float>(static_cast<std::size_t>(bins));
    const auto keys = in.get<std::uint64_t>();
    if (keys > in.remaining() / sizeof(float)) in.garbled("ring key count");
    d.ring_key = in.get_array<float>(static_cast<std::size_t>(keys));
    d.occupied_bins = static_cast<int>(in.get<std::int64_t>());
    const auto valid = in.get<std::uint8_t>();
    if (valid > 1) in.garbled("valid flag");
    d.valid = valid == 1;
  });
}

std::vector<std::byte> encode_registrations(std::span<const PairRegistration> registrations,
                                            double seconds, ScanReads reads,
                                            std::uint64_t peak_rss_bytes) {
  return encode_items(registrations, seconds, reads, peak_rss_bytes, write_registration);
}

WorkAnswer read_loop_checks(std::span<const std::byte> bytes, const std::string& what,
                            std::span<const std::size_t> expected, std::vector<LoopCheck>* checks) {
  return read_items(bytes, what, expected, "check", [&](ByteReader& in, std::size_t k) {
    LoopCheck& check = (*checks)[k];
    const auto verdict = in.get<std::uint8_t>();
    if (verdict > static_cast<std::uint8_t>(LoopVerdict::kTooFarFromGuess)) in.garbled("verdict");
    check.verdict = static_cast<LoopVerdict>(verdict);
    check.inlier_fraction = in.get<double>();
    check.registration = read_registration(in);
  });
}

WorkAnswer read_registrations(std::span<const std::byte> bytes, const std::string& what,
                              std::span<const std::size_t> expected,
                              std::vector<PairRegistration>* registrations) {
  return read_items(bytes, what, expected, "registration", [&](ByteReader& in, std::size_t k) {
    (*registrations)[k] = read_registration(in);
  });
}

std::vector<std::byte> encode_job(const MpiFrameSource& source,
                                  const GlobalRegistrationOptions& options,
                                  std::span<const FramePair> pairs,
                                  std::span<const Eigen::Isometry3d> T_world_frame,
                                  const std::vector<std::vector<std::size_t>>& shares) {
  return encode_work_job(source, options, pairs, T_world_frame, shares);
}

BuildJob decode_job(std::span<const std::byte> bytes) {
  return decode_work_job<BuildJob>(bytes, "the job from rank 0", read_global_registration_options);
}

std::vector<std::byte> encode_overlap_job(const MpiFrameSource& source,
                                          const DenseGraphOptions& options,
                                          std::span<const FramePair> pairs,
                                          std::span<const Eigen::Isometry3d> T_world_frame,
                                          const std::vector<std::vector<std::size_t>>& shares) {
  return encode_work_job(source, options, pairs, T_world_frame, shares);
}

OverlapJob decode_overlap_job(std::span<const std::byte> bytes) {
  return decode_work_job<OverlapJob>(bytes, "the overlap job from rank 0",
                                     read_dense_graph_options);
}

std::vector<std::byte> encode_overlaps(std::span<const FramePair> pairs, double measure_s,
                                       ScanReads reads, std::uint64_t peak_rss_bytes) {
  return encode_items(pairs, measure_s, reads, peak_rss_bytes,
                      [](ByteWriter& out, const FramePair& pair) { out.put(pair.overlap); });
}

WorkAnswer read_overlap_answer(std::span<const std::byte> bytes, const std::string& what,
                               std::span<const std::size_t> expected,
                               std::vector<FramePair>* pairs) {
  return read_items(bytes, what, expected, "pair", [&](ByteReader& in, std::size_t k) {
    const double overlap = in.get<double>();
    if (!(overlap >= 0.0 && overlap <= 1.0))
      in.garbled("overlap " + std::to_string(overlap) + " of pair " + std::to_string(k));
    (*pairs)[k].overlap = overlap;
  });
}

std::vector<std::uint64_t> file_sizes(const std::vector<ScanFile>& files) {
  std::vector<std::uint64_t> out;
  out.reserve(files.size());
  for (const ScanFile& file : files) {
    std::error_code error;
    const std::uintmax_t size = std::filesystem::file_size(file.path, error);
    out.push_back(error ? kUnknownSize : static_cast<std::uint64_t>(size));
  }
  return out;
}

void check_same_files(const MpiFrameSource& source) {
  for (std::size_t k = 0; k < source.files.size() && k < source.file_sizes.size(); ++k) {
    const std::uint64_t there = source.file_sizes[k];
    if (there == kUnknownSize) continue;  // rank 0 reports its own unreadable file
    std::error_code error;
    const std::uintmax_t here = std::filesystem::file_size(source.files[k].path, error);
    const std::string name = source.files[k].path.string();
    if (error) {
      throw Error(name + ": cannot be read on this rank (" + error.message() +
                  "); every rank must read the same files (a shared filesystem)");
    }
    if (static_cast<std::uint64_t>(here) != there) {
      throw Error(name + ": " + std::to_string(here) + " bytes on this rank but " +
                  std::to_string(there) +
                  " bytes on rank 0; every rank must read the same files (a shared filesystem)");
    }
  }
}

std::vector<std::vector<std::size_t>> split_order(std::span<const std::size_t> order, int ranks) {
  std::vector<std::vector<std::size_t>> shares(static_cast<std::size_t>(ranks));
  const std::size_t n = order.size(), r = shares.size();
  for (std::size_t q = 0; q < r; ++q) {
    shares[q].assign(order.begin() + static_cast<std::ptrdiff_t>(q * n / r),
                     order.begin() + static_cast<std::ptrdiff_t>((q + 1) * n / r));
  }
  return shares;
}

std::vector<std::byte> encode_held(const RegistrationShare& share, double build_s, ScanReads reads,
                                   std::uint64_t peak_rss_bytes) {
  std::vector<std::byte> bytes;
  ByteWriter out(bytes);
  write_answer_header(out, build_s, reads, peak_rss_bytes, share.size());
  const RegistrationFactorStats& stats = share.stats();
  static_assert(field_count<RegistrationFactorStats>() == 8, "encode_held: send the new field");
  for (const std::size_t count : {stats.num_factors, stats.num_correspondences, stats.num_rows,
                                  stats.correspondence_bytes, stats.residual_bytes})
    out.put(static_cast<std::uint64_t>(count));
  out.put(stats.correspondence_s);
  out.put(stats.compression_s);
  out.put(stats.minimum_s);
  for (const std::size_t b : share.correspondence_bytes()) out.put(static_cast<std::uint64_t>(b));
  for (const std::size_t b : share.residual_bytes()) out.put(static_cast<std::uint64_t>(b));
  return bytes;
}

WorkAnswer read_held_answer(std::span<const std::byte> bytes, const std::string& what,
                            std::size_t count, HeldAnswer* held) {
  ByteReader in(bytes, what);
  const WorkAnswer answer = read_answer_header(in, count, "factor");
  const auto get = [&in] { return static_cast<std::size_t>(in.get<std::uint64_t>()); };
  RegistrationFactorStats& stats = held->stats;
  stats.num_factors = get();
  stats.num_correspondences = get();
  stats.num_rows = get();
  stats.correspondence_bytes = get();
  stats.residual_bytes = get();
  stats.correspondence_s = in.get<double>();
  stats.compression_s = in.get<double>();
  stats.minimum_s = in.get<double>();
  if (stats.num_factors != count) in.garbled("factor count of the stats");
  if (count > in.remaining() / (2 * sizeof(std::uint64_t))) in.garbled("factor count");
  held->correspondence_bytes.resize(count);
  held->residual_bytes.resize(count);
  for (std::size_t& b : held->correspondence_bytes) b = get();
  for (std::size_t& b : held->residual_bytes) b = get();
  in.expect_end();
  return answer;
}

std::vector<std::byte> encode_records(std::size_t first, std::span<const double> records) {
  std::vector<std::byte> bytes;
  bytes.reserve(1 + 2 * sizeof(std::uint64_t) + records.size_bytes());
  ByteWriter out(bytes);
  out.put(std::uint8_t{kRecords});
  out.put(static_cast<std::uint64_t>(first));
  out.put(static_cast<std::uint64_t>(records.size()));
  out.put_array(records);
  return bytes;
}

std::vector<std::byte> encode_done() { return {std::byte{kStreamDone}}; }

bool read_records(std::span<const std::byte> bytes, const std::string& what, std::size_t* first,
                  std::vector<double>* records) {
  ByteReader in(bytes, what);
  const auto kind = in.get<std::uint8_t>();
  if (kind == kFailed || kind == kStreamDone) return false;
  if (kind != kRecords) in.garbled("message kind " + std::to_string(kind));
  *first = static_cast<std::size_t>(in.get<std::uint64_t>());
  const auto count = in.get<std::uint64_t>();
  if (count > in.remaining() / sizeof(double)) in.garbled("record count");
  *records = in.get_array<double>(static_cast<std::size_t>(count));
  in.expect_end();
  return true;
}

std::vector<std::byte> encode_numbers(std::span<const double> numbers,
                                      std::uint64_t peak_rss_bytes) {
  std::vector<std::byte> bytes;
  ByteWriter out(bytes);
  write_answer_header(out, 0.0, ScanReads{}, peak_rss_bytes, numbers.size());
  out.put_array(numbers);
  return bytes;
}

WorkAnswer read_numbers(std::span<const std::byte> bytes, const std::string& what,
                        std::size_t count, std::vector<double>* numbers) {
  ByteReader in(bytes, what);
  const WorkAnswer answer = read_answer_header(in, count, "number");
  *numbers = in.get_array<double>(count);
  in.expect_end();
  return answer;
}

std::vector<std::byte> encode_failure(const std::string& message) {
  std::vector<std::byte> bytes;
  ByteWriter out(bytes);
  out.put(std::uint8_t{kFailed});
  out.put_string(message);
  return bytes;
}

std::string answer_failure(std::span<const std::byte> bytes, const std::string& what) {
  ByteReader in(bytes, what);
  if (in.get<std::uint8_t>() != kFailed) return {};
  std::string message = in.get_string();
  return message.empty() ? std::string("failed") : message;
}

}  // namespace carat::cli
