// Registration factors as bytes (what carat map's MPI ranks send to rank 0): every sampling's
// factors read back equal bit for bit (rows, Jacobians, squared norm, normal equations, counts,
// bytes, the bytes written again), a solve over factors moved through bytes equals the solve
// over the factors as built, and truncated or garbled bytes are refused with carat::Error.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <cstring>
#include <limits>
#include <memory>
#include <numeric>
#include <span>
#include <string>
#include <vector>

#include "carat/base/byte_stream.hpp"
#include "carat/base/error.hpp"
#include "carat/registration/dense_graph.hpp"
#include "carat/registration/factor_serialization.hpp"
#include "carat/registration/frame_store.hpp"
#include "carat/registration/global_registration.hpp"
#include "carat/registration/held_factors.hpp"
#include "carat/registration/option_serialization.hpp"
#include "carat/residuals/block_serialization.hpp"
#include "carat/residuals/relative_pose_block.hpp"
#include "carat/sim/pipeline.hpp"
#include "carat/solver/se3.hpp"
#include "registration_test_drive.hpp"

namespace carat {
namespace {

using ::testing::HasSubstr;

/// A 16-frame drive with drift: frames, drifted poses and the dense graph at them.
struct Drive {
  std::vector<std::shared_ptr<const Frame>> frames;
  std::vector<Eigen::Isometry3d> initial;
  std::vector<FramePair> pairs;
};

const Drive& drive() {
  static const Drive d = [] {
    SyntheticPipeline pipeline = test::simulate_test_drive(
        5, 16, 1, {.seed = 2, .translation_sigma = 0.005, .rotation_sigma_deg = 0.03});
    Drive out;
    out.frames = std::move(pipeline.frames);
    out.initial = std::move(pipeline.T_world_drift);
    FrameStore store(out.frames);
    out.pairs = build_dense_graph(store, out.initial);
    return out;
  }();
  return d;
}

GlobalRegistrationOptions options_for(ResidualSampling sampling) {
  GlobalRegistrationOptions options;
  options.sampling = sampling;
  options.num_threads = 2;
  return options;
}

std::vector<RegistrationFactor> build(const GlobalRegistrationOptions& options) {
  FrameStore store(drive().frames);
  return build_registration_factors(store, drive().pairs, {}, drive().initial, options);
}

/// Bitwise equality of two arrays of doubles (NaN-safe, -0 != +0).
bool same_bits(std::span<const double> a, std::span<const double> b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size_bytes()) == 0;
}

/// Every row, Jacobian, squared norm and normal equation of the two blocks at `values`.
void expect_identical(const ResidualBlock& a, const ResidualBlock& b, ParameterPointers values) {
  ASSERT_EQ(a.num_rows(), b.num_rows());
  ASSERT_EQ(a.memory_bytes(), b.memory_bytes());
  ASSERT_EQ(a.reduced_dim(), b.reduced_dim());
  const int n = a.num_rows(), r = a.reduced_dim();
  std::vector<int> rows(static_cast<std::size_t>(n));
  std::iota(rows.begin(), rows.end(), 0);
  std::vector<double> ra(rows.size()), rb(rows.size()), ja(rows.size() * 6), jb(rows.size() * 6);
  a.evaluate_rows(values, rows, ra.data(), ja.data());
  b.evaluate_rows(values, rows, rb.data(), jb.data());
  EXPECT_TRUE(same_bits(ra, rb));
  EXPECT_TRUE(same_bits(ja, jb));
  const double sa = a.squared_norm(values), sb = b.squared_norm(values);
  EXPECT_TRUE(same_bits({&sa, 1}, {&sb, 1}));
  Eigen::MatrixXd Ha = Eigen::MatrixXd::Zero(r, r), Hb = Eigen::MatrixXd::Zero(r, r);
  Eigen::VectorXd ba = Eigen::VectorXd::Zero(r), bb = Eigen::VectorXd::Zero(r);
  const double ca = a.accumulate(values, Ha, ba), cb = b.accumulate(values, Hb, bb);
  EXPECT_TRUE(same_bits({&ca, 1}, {&cb, 1}));
  EXPECT_TRUE(same_bits({Ha.data(), static_cast<std::size_t>(r * r)},
                        {Hb.data(), static_cast<std::size_t>(r * r)}));
  EXPECT_TRUE(same_bits({ba.data(), static_cast<std::size_t>(r)},
                        {bb.data(), static_cast<std::size_t>(r)}));
}

class FactorBytesTest : public ::testing::TestWithParam<ResidualSampling> {};

TEST_P(FactorBytesTest, RoundTripIsBitIdentical) {
  GlobalRegistrationOptions options = options_for(GetParam());
  options.factor_excess_cauchy_scale = 1.0;  // a model minimum to carry
  const std::vector<RegistrationFactor> factors = build(options);
  ASSERT_FALSE(factors.empty());
  for (std::size_t k = 0; k < factors.size(); ++k) {
    SCOPED_TRACE("factor " + std::to_string(k));
    const RegistrationFactor& f = factors[k];
    ASSERT_TRUE(has_byte_form(*f.block));
    const std::vector<std::byte> bytes = serialize_factor(f);
    const RegistrationFactor g = deserialize_factor(bytes, "factor");
    EXPECT_EQ(g.correspondences, f.correspondences);
    EXPECT_EQ(g.correspondence_bytes, f.correspondence_bytes);
    EXPECT_EQ(g.correspondence_s, f.correspondence_s);
    EXPECT_EQ(g.compression_s, f.compression_s);
    EXPECT_EQ(g.minimum_s, f.minimum_s);
    EXPECT_EQ(g.minimum, f.minimum);
    EXPECT_EQ(serialize_factor(g), bytes);
    // At the initial poses and 0.3 m / a few degrees away from them.
    const FramePair& pair = drive().pairs[k];
    for (const double shift : {0.0, 0.3}) {
      std::array<double, 7> target{}, source{};
      se3::to_storage(drive().initial[static_cast<std::size_t>(pair.target)], target.data());
      se3::Vector6d step;
      step << 0.05 * shift, -0.02 * shift, 0.04 * shift, shift, -shift, 0.5 * shift;
      se3::to_storage(drive().initial[static_cast<std::size_t>(pair.source)] * se3::exp(step),
                      source.data());
      const double* values[2] = {target.data(), source.data()};
      expect_identical(*f.block, *g.block, values);
    }
  }
}

TEST_P(FactorBytesTest, SolveOverFactorsMovedThroughBytesIsTheSame) {
  GlobalRegistrationOptions options = options_for(GetParam());
  options.rounds = 2;
  const Drive& d = drive();
  FrameStore store(d.frames);
  const GlobalRegistrationResult direct = optimize_registration(store, d.pairs, d.initial, options);
  std::size_t moved = 0;
  const GlobalRegistrationResult through_bytes = optimize_registration(
      [&](std::span<const Eigen::Isometry3d> T_world_frame) {
        std::vector<RegistrationFactor> factors =
            build_registration_factors(store, d.pairs, {}, T_world_frame, options);
        for (RegistrationFactor& f : factors) {
          const std::vector<std::byte> bytes = serialize_factor(f);
          moved += bytes.size();
          f = deserialize_factor(bytes, "factor");
        }
        return factors;
      },
      d.pairs, d.initial, options);
  EXPECT_GT(moved, 0u);
  ASSERT_EQ(direct.T_world_frame.size(), through_bytes.T_world_frame.size());
  EXPECT_EQ(direct.rounds, through_bytes.rounds);
  EXPECT_EQ(direct.summary.num_iterations, through_bytes.summary.num_iterations);
  for (std::size_t i = 0; i < direct.T_world_frame.size(); ++i) {
    EXPECT_TRUE(same_bits({direct.T_world_frame[i].matrix().data(), 16},
                          {through_bytes.T_world_frame[i].matrix().data(), 16}))
        << "pose " << i;
  }
  EXPECT_EQ(direct.factor_costs, through_bytes.factor_costs);
}

/// A round's factors held in `shares` stretches of the block order, each a RegistrationShare,
/// as the ranks of an MPI job hold them.
class SharesHeld final : public HeldRegistrationFactors {
 public:
  SharesHeld(FrameStore& store, std::span<const FramePair> pairs,
             std::span<const Eigen::Isometry3d> T_world_start, std::span<const std::size_t> order,
             const GlobalRegistrationOptions& options, std::size_t shares)
      : pairs_(pairs.size()) {
    for (std::size_t r = 0; r < shares; ++r) {
      std::vector<std::size_t> indices(
          order.begin() + static_cast<std::ptrdiff_t>(r * order.size() / shares),
          order.begin() + static_cast<std::ptrdiff_t>((r + 1) * order.size() / shares));
      shares_.push_back(std::make_unique<RegistrationShare>(
          pairs, indices, build_registration_factors(store, pairs, indices, T_world_start, options),
          T_world_start, options));
      for (const std::size_t k : indices) {
        variables_.push_back(VariableId{pairs[k].target});
        variables_.push_back(VariableId{pairs[k].source});
      }
      indices_.push_back(std::move(indices));
    }
  }
  std::size_t num_blocks() const override { return variables_.size() / 2; }
  std::span<const VariableId> variables(std::size_t k) const override {
    return std::span<const VariableId>(variables_).subspan(2 * k, 2);
  }
  void linearize(std::span<const double> values, const BlockRecordSink& sink) override {
    std::size_t first = 0;
    for (const auto& share : shares_) {
      share->linearize(values, [&](std::size_t run, std::span<const double> records) {
        sink(first + run, records);
      });
      first += share->size();
    }
  }
  void costs(std::span<const double> values, const BlockRecordSink& sink) override {
    std::size_t first = 0;
    for (const auto& share : shares_) {
      share->costs(values, [&](std::size_t run, std::span<const double> costs) {
        sink(first + run, costs);
      });
      first += share->size();
    }
  }
  RegistrationFactorStats stats() const override {
    RegistrationFactorStats out;
    for (const auto& share : shares_) {
      out.num_factors += share->stats().num_factors;
      out.num_correspondences += share->stats().num_correspondences;
      out.num_rows += share->stats().num_rows;
      out.correspondence_bytes += share->stats().correspondence_bytes;
      out.residual_bytes += share->stats().residual_bytes;
    }
    return out;
  }
  std::vector<std::size_t> correspondence_bytes() const override {
    return per_pair([](const RegistrationShare& s) { return s.correspondence_bytes(); });
  }
  std::vector<std::size_t> residual_bytes() const override {
    return per_pair([](const RegistrationShare& s) { return s.residual_bytes(); });
  }
  std::vector<double> factor_costs(std::span<const double> values) override {
    std::vector<double> out(pairs_);
    for (std::size_t r = 0; r < shares_.size(); ++r) {
      const std::vector<double> costs = shares_[r]->factor_costs(values);
      for (std::size_t q = 0; q < costs.size(); ++q) out[indices_[r][q]] = costs[q];
    }
    return out;
  }

 private:
  template <class Field>
  std::vector<std::size_t> per_pair(Field field) const {
    std::vector<std::size_t> out(pairs_);
    for (std::size_t r = 0; r < shares_.size(); ++r) {
      const std::span<const std::size_t> values = field(*shares_[r]);
      for (std::size_t q = 0; q < values.size(); ++q) out[indices_[r][q]] = values[q];
    }
    return out;
  }
  std::size_t pairs_;
  std::vector<std::unique_ptr<RegistrationShare>> shares_;
  std::vector<std::vector<std::size_t>> indices_;
  std::vector<VariableId> variables_;
};

TEST_P(FactorBytesTest, FactorsHeldInSharesSolveBitForBitAsInOneProblem) {
  GlobalRegistrationOptions options = options_for(GetParam());
  options.rounds = 2;
  options.factor_cauchy_scale = 2.0;
  options.covariance = true;
  const Drive& d = drive();
  FrameStore store(d.frames);
  const GlobalRegistrationResult direct = optimize_registration(store, d.pairs, d.initial, options);
  for (const std::size_t shares : {std::size_t{1}, std::size_t{3}}) {
    SCOPED_TRACE(std::to_string(shares) + " shares");
    const GlobalRegistrationResult held = optimize_held_registration(
        [&](std::span<const Eigen::Isometry3d> T_world_start, std::span<const std::size_t> order) {
          return std::make_shared<SharesHeld>(store, d.pairs, T_world_start, order, options,
                                              shares);
        },
        d.pairs, d.initial, options);
    ASSERT_EQ(direct.T_world_frame.size(), held.T_world_frame.size());
    EXPECT_EQ(direct.rounds, held.rounds);
    EXPECT_EQ(direct.summary.num_iterations, held.summary.num_iterations);
    EXPECT_EQ(direct.summary.final_cost, held.summary.final_cost);
    for (std::size_t i = 0; i < direct.T_world_frame.size(); ++i) {
      EXPECT_TRUE(same_bits({direct.T_world_frame[i].matrix().data(), 16},
                            {held.T_world_frame[i].matrix().data(), 16}))
          << "pose " << i;
    }
    EXPECT_EQ(direct.factor_costs, held.factor_costs);
    EXPECT_EQ(direct.factor_residual_bytes, held.factor_residual_bytes);
    ASSERT_EQ(direct.covariance.size(), held.covariance.size());
    for (std::size_t i = 0; i < direct.covariance.size(); ++i)
      EXPECT_TRUE(same_bits({direct.covariance[i].data(), 36}, {held.covariance[i].data(), 36}));
  }
}

INSTANTIATE_TEST_SUITE_P(Samplings, FactorBytesTest,
                         ::testing::Values(ResidualSampling::kExact, ResidualSampling::kLossless,
                                           ResidualSampling::kFull, ResidualSampling::kRandom),
                         [](const auto& param_info) {
                           return std::string(to_string(param_info.param));
                         });

/// One factor's bytes for the bad-input tests.
std::vector<std::byte> one_factor(ResidualSampling sampling) {
  const GlobalRegistrationOptions options = options_for(sampling);
  FrameStore store(drive().frames);
  const std::size_t first = 0;
  return serialize_factor(
      build_registration_factors(store, drive().pairs, {&first, 1}, drive().initial, options)[0]);
}

/// `bytes` with a new checksum, so that a change inside passes the checksum.
std::vector<std::byte> resealed(std::vector<std::byte> bytes) {
  const std::uint64_t sum = fnv1a_checksum(std::span(bytes).first(bytes.size() - 8));
  std::memcpy(bytes.data() + bytes.size() - 8, &sum, 8);
  return bytes;
}

TEST(FactorBytesBadInputTest, EveryTruncationIsRefused) {
  for (const ResidualSampling sampling : {ResidualSampling::kExact, ResidualSampling::kLossless}) {
    const std::vector<std::byte> bytes = one_factor(sampling);
    for (std::size_t n = 0; n < bytes.size(); ++n) {
      EXPECT_THAT([&] { deserialize_factor(std::span(bytes).first(n), "the answer"); },
                  ::testing::ThrowsMessage<Error>(HasSubstr("the answer: truncated")))
          << n << " of " << bytes.size() << " bytes";
    }
  }
}

TEST(FactorBytesBadInputTest, EveryChangedByteIsRefused) {
  for (const ResidualSampling sampling : {ResidualSampling::kExact, ResidualSampling::kLossless}) {
    const std::vector<std::byte> bytes = one_factor(sampling);
    for (std::size_t at = 0; at < bytes.size(); ++at) {
      std::vector<std::byte> changed = bytes;
      changed[at] ^= std::byte{0x10};
      EXPECT_THAT([&] { deserialize_factor(changed, "the answer"); },
                  ::testing::ThrowsMessage<Error>(HasSubstr("the answer: ")))
          << "byte " << at;
    }
    std::vector<std::byte> longer = bytes;
    longer.push_back(std::byte{0});
    EXPECT_THAT([&] { deserialize_factor(longer, "x"); },
                ::testing::ThrowsMessage<Error>(HasSubstr("x: garbled")));
  }
}

TEST(FactorBytesBadInputTest, ValuesNoWriterProducesAreRefused) {
  // Byte 12 is the block's tag (after the factor's tag and length).
  std::vector<std::byte> bytes = one_factor(ResidualSampling::kLossless);
  bytes[12] = std::byte{9};
  EXPECT_THAT([&] { deserialize_factor(resealed(bytes), "f"); },
              ::testing::ThrowsMessage<Error>(HasSubstr("f: garbled: unknown block tag 9")));
  // A lossless block's rank follows its 15 doubles of reference pose and centre.
  bytes = one_factor(ResidualSampling::kLossless);
  bytes[13 + 120] = std::byte{14};
  EXPECT_THAT([&] { deserialize_factor(resealed(bytes), "f"); },
              ::testing::ThrowsMessage<Error>(HasSubstr("lossless block of rank 14")));
  bytes = one_factor(ResidualSampling::kLossless);
  bytes[13 + 121] = bytes[13 + 122];  // the pivot order repeats a coordinate
  EXPECT_THAT([&] { deserialize_factor(resealed(bytes), "f"); },
              ::testing::ThrowsMessage<Error>(HasSubstr("not a permutation")));
  // A non-finite value in an exact factor's rows.
  bytes = one_factor(ResidualSampling::kExact);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::memcpy(bytes.data() + 13 + 1 + 16 + 8, &nan, 8);
  EXPECT_THAT([&] { deserialize_factor(resealed(bytes), "f"); },
              ::testing::ThrowsMessage<Error>(HasSubstr("non-finite")));
}

TEST(FactorBytesBadInputTest, BlocksWithoutAByteFormAreRefused) {
  const RelativePoseBlock block(Eigen::Isometry3d::Identity(),
                                Eigen::Matrix<double, 6, 6>::Identity());
  EXPECT_FALSE(has_byte_form(block));
  std::vector<std::byte> bytes;
  ByteWriter out(bytes);
  EXPECT_THAT([&] { write_block(block, out); },
              ::testing::ThrowsMessage<Error>(HasSubstr("no byte form")));
  EXPECT_THAT([] { serialize_factor(RegistrationFactor{}); },
              ::testing::ThrowsMessage<Error>(HasSubstr("no block")));
}

/// Registration options with every field away from its default (the callbacks set).
GlobalRegistrationOptions unusual_options() {
  GlobalRegistrationOptions o;
  o.sampling = ResidualSampling::kLossless;
  o.residuals = 57;
  o.max_correspondence_distance = 0.75;
  o.min_correspondences = 31;
  o.seed = 0xfedcba9876543210ull;
  o.num_threads = 3;
  o.factor_cauchy_scale = 0.125;
  o.factor_excess_cauchy_scale = 0.0625;
  o.rounds = 4;
  o.round_translation_tolerance = 2e-3;
  o.round_rotation_tolerance = 3e-4;
  o.covariance = true;
  o.iteration_callback = [](const IterationSummary&, std::span<const Eigen::Isometry3d>) {
    return CallbackResult::kContinue;
  };
  SolverOptions& v = o.solver;
  v.method = Method::kGaussNewton;
  v.ordering = Ordering::kMetis;
  v.linear_solver = LinearSolver::kCholesky;
  v.max_linear_system_bytes = 1e9;
  v.max_iterations = 7;
  v.function_tolerance = 1e-5;
  v.gradient_tolerance = 1e-9;
  v.parameter_tolerance = 1e-7;
  v.initial_trust_region_radius = 1e3;
  v.lm_start = LmStart::kTrustRegion;
  v.gauss_newton_phase_min_gain = 0.25;
  v.gauss_newton_phase_radius = 1e9;
  v.max_trust_region_radius = 1e15;
  v.max_trust_region_growth = 8.0;
  v.min_trust_region_radius = 1e-30;
  v.min_relative_decrease = 2e-3;
  v.min_lm_diagonal = 1e-5;
  v.max_lm_diagonal = 1e30;
  v.reuse_factorization = !v.reuse_factorization;
  v.factor_reuse_ratio = 1.2;
  v.anderson_memory = 3;
  v.num_threads = 5;
  v.record_iterations = !v.record_iterations;
  v.iteration_callback = [](const IterationSummary&) { return CallbackResult::kAbort; };
  v.update_state_every_iteration = !v.update_state_every_iteration;
  v.check_blocks = !v.check_blocks;
  return o;
}

std::vector<std::byte> option_bytes(const GlobalRegistrationOptions& options) {
  std::vector<std::byte> bytes;
  ByteWriter out(bytes);
  write_options(out, options);
  return bytes;
}

TEST(OptionBytesTest, EveryFieldButTheCallbacksRoundTrips) {
  const GlobalRegistrationOptions sent = unusual_options();
  const std::vector<std::byte> bytes = option_bytes(sent);
  ByteReader in(bytes, "options");
  const GlobalRegistrationOptions got = read_global_registration_options(in);
  in.expect_end();
  EXPECT_EQ(got.sampling, sent.sampling);
  EXPECT_EQ(got.residuals, sent.residuals);
  EXPECT_EQ(got.max_correspondence_distance, sent.max_correspondence_distance);
  EXPECT_EQ(got.min_correspondences, sent.min_correspondences);
  EXPECT_EQ(got.seed, sent.seed);
  EXPECT_EQ(got.num_threads, sent.num_threads);
  EXPECT_EQ(got.factor_cauchy_scale, sent.factor_cauchy_scale);
  EXPECT_EQ(got.factor_excess_cauchy_scale, sent.factor_excess_cauchy_scale);
  EXPECT_EQ(got.rounds, sent.rounds);
  EXPECT_EQ(got.round_translation_tolerance, sent.round_translation_tolerance);
  EXPECT_EQ(got.round_rotation_tolerance, sent.round_rotation_tolerance);
  EXPECT_EQ(got.covariance, sent.covariance);
  EXPECT_FALSE(got.iteration_callback);
  const SolverOptions &a = got.solver, &b = sent.solver;
  EXPECT_EQ(a.method, b.method);
  EXPECT_EQ(a.ordering, b.ordering);
  EXPECT_EQ(a.linear_solver, b.linear_solver);
  EXPECT_EQ(a.max_linear_system_bytes, b.max_linear_system_bytes);
  EXPECT_EQ(a.max_iterations, b.max_iterations);
  EXPECT_EQ(a.function_tolerance, b.function_tolerance);
  EXPECT_EQ(a.gradient_tolerance, b.gradient_tolerance);
  EXPECT_EQ(a.parameter_tolerance, b.parameter_tolerance);
  EXPECT_EQ(a.initial_trust_region_radius, b.initial_trust_region_radius);
  EXPECT_EQ(a.lm_start, b.lm_start);
  EXPECT_EQ(a.gauss_newton_phase_min_gain, b.gauss_newton_phase_min_gain);
  EXPECT_EQ(a.gauss_newton_phase_radius, b.gauss_newton_phase_radius);
  EXPECT_EQ(a.max_trust_region_radius, b.max_trust_region_radius);
  EXPECT_EQ(a.max_trust_region_growth, b.max_trust_region_growth);
  EXPECT_EQ(a.min_trust_region_radius, b.min_trust_region_radius);
  EXPECT_EQ(a.min_relative_decrease, b.min_relative_decrease);
  EXPECT_EQ(a.min_lm_diagonal, b.min_lm_diagonal);
  EXPECT_EQ(a.max_lm_diagonal, b.max_lm_diagonal);
  EXPECT_EQ(a.reuse_factorization, b.reuse_factorization);
  EXPECT_EQ(a.factor_reuse_ratio, b.factor_reuse_ratio);
  EXPECT_EQ(a.anderson_memory, b.anderson_memory);
  EXPECT_EQ(a.num_threads, b.num_threads);
  EXPECT_EQ(a.record_iterations, b.record_iterations);
  EXPECT_FALSE(a.iteration_callback);
  EXPECT_EQ(a.update_state_every_iteration, b.update_state_every_iteration);
  EXPECT_EQ(a.check_blocks, b.check_blocks);
  // Read back and written again: the same bytes.
  EXPECT_EQ(option_bytes(got), bytes);

  OpenScansOptions scans;
  scans.read.drop_non_finite = true;
  scans.read.max_points = 12345;
  scans.preprocess.voxel_size = 0.3;
  scans.preprocess.covariance_neighbors = 12;
  scans.preprocess.min_points = 40;
  scans.preprocess.num_threads = 2;
  scans.max_bytes = 987654321;
  scans.require_constrained = false;
  scans.num_threads = 3;
  std::vector<std::byte> more;
  ByteWriter out(more);
  write_options(out, scans);
  ByteReader back(more, "scan options");
  const OpenScansOptions got_scans = read_open_scans_options(back);
  back.expect_end();
  EXPECT_EQ(got_scans.read.drop_non_finite, true);
  EXPECT_EQ(got_scans.read.max_points, 12345u);
  EXPECT_EQ(got_scans.preprocess.voxel_size, 0.3);
  EXPECT_EQ(got_scans.preprocess.covariance_neighbors, 12);
  EXPECT_EQ(got_scans.preprocess.min_points, 40);
  EXPECT_EQ(got_scans.preprocess.num_threads, 2);
  EXPECT_EQ(got_scans.max_bytes, 987654321u);
  EXPECT_EQ(got_scans.require_constrained, false);
  EXPECT_EQ(got_scans.num_threads, 3);
  DenseGraphOptions graph;
  graph.overlap_threshold = 0.35;
  graph.voxel_size = 0.75;
  graph.max_distance = 42.5;
  graph.overlap_stride = 7;
  graph.num_threads = 3;
  std::vector<std::byte> graph_bytes;
  ByteWriter graph_out(graph_bytes);
  write_options(graph_out, graph);
  ByteReader graph_in(graph_bytes, "graph options");
  const DenseGraphOptions got_graph = read_dense_graph_options(graph_in);
  graph_in.expect_end();
  EXPECT_EQ(got_graph.overlap_threshold, 0.35);
  EXPECT_EQ(got_graph.voxel_size, 0.75);
  EXPECT_EQ(got_graph.max_distance, 42.5);
  EXPECT_EQ(got_graph.overlap_stride, 7);
  EXPECT_EQ(got_graph.num_threads, 3);
  ByteReader short_in(std::span<const std::byte>(graph_bytes).first(graph_bytes.size() - 1),
                      "graph options");
  EXPECT_THROW(read_dense_graph_options(short_in), Error);
}

TEST(OptionBytesTest, TruncatedOrGarbledBytesAreRefused) {
  const std::vector<std::byte> bytes = option_bytes(unusual_options());
  for (std::size_t size = 0; size < bytes.size(); ++size) {
    ByteReader in(std::span<const std::byte>(bytes).first(size), "options from rank 0");
    EXPECT_THROW(read_global_registration_options(in), Error) << size << " bytes";
  }
  std::vector<std::byte> bad = bytes;
  bad[0] = std::byte{9};  // sampling: no such value
  ByteReader in(bad, "options from rank 0");
  try {
    read_global_registration_options(in);
    FAIL() << "a sampling of 9 was read";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("options from rank 0: garbled: sampling 9"));
  }
}

}  // namespace
}  // namespace carat
