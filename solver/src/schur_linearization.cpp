#include "schur_linearization.hpp"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>

#include "carat/base/stopwatch.hpp"
#include "schur_kernels.hpp"

namespace carat::internal {
namespace {

std::size_t at(int k) { return static_cast<std::size_t>(k); }

}  // namespace

SchurLinearization::SchurLinearization(const Problem& problem, const SchurStructure& structure,
                                       SchurValues& values)
    : s_(structure), values_(values) {
  if (!s_.fused) return;
  plan_direct_blocks(problem);
  plan_chunks();
  plan_other_blocks(problem);
}

/// Direct: a block of a few rows, no loss and no reduced form is scattered from its Jacobian
/// rows (J_p^T J_p into V, J_c^T J_p into W, J_c^T J_c into its camera's slot), without its
/// D x D H. Its camera (if any) is the row variable of its one edge contribution.
void SchurLinearization::plan_direct_blocks(const Problem& problem) {
  const auto blocks = problem.blocks();
  direct_.assign(s_.pt_contribs.size(), 0);
  direct_rows_.assign(s_.pt_contribs.size(), 0);
  direct_cam_local_.assign(s_.pt_contribs.size(), -1);
  direct_edge_.assign(s_.pt_contribs.size(), kNoEdge);
  for (std::size_t e = 0; e < s_.edge_cam.size(); ++e) {
    for (std::size_t q = s_.edge_contrib_begin[e]; q < s_.edge_contrib_begin[e + 1]; ++q) {
      direct_edge_[s_.edge_contrib_source[q]] = e;
      direct_cam_local_[s_.edge_contrib_source[q]] = s_.edge_contribs[q].row_local;
    }
  }
  // Read in block order (the blocks' storage in turn), then listed in point order.
  std::vector<int> rows_of(blocks.size(), 0);
  std::vector<char> direct_of(blocks.size(), 0);
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    const auto& entry = blocks[i];
    rows_of[i] = entry.block->num_rows();
    direct_of[i] =
        !entry.loss && rows_of[i] <= kDirectRows && entry.block->reduced_dim() == s_.block_dims[i];
  }
  for (std::size_t q = 0; q < s_.pt_contribs.size(); ++q) {
    const auto i = static_cast<std::size_t>(s_.pt_contribs[q].first);
    direct_rows_[q] = rows_of[i];
    direct_[q] = direct_of[i];
  }
  edge_assigned_.assign(s_.edge_cam.size(), 0);
  for (std::size_t e = 0; e < s_.edge_cam.size(); ++e) {
    edge_assigned_[e] = s_.edge_contrib_begin[e + 1] == s_.edge_contrib_begin[e] + 1 &&
                        direct_[s_.edge_contrib_source[s_.edge_contrib_begin[e]]];
  }
}

void SchurLinearization::plan_chunks() {
  const std::size_t np = s_.pt_dim.size();
  const std::size_t nc = s_.cam_dim.size();
  // Points per chunk: enough that a chunk's edges are many per camera it touches (about
  // kEdgesPerSlot for each camera of the problem), so that its slots are few beside its blocks; at
  // least 1024. (The chunk is evaluated and scattered a piece of points at a time, so its size
  // does not set the buffer's.) A function of the problem alone, so results do not depend on the
  // number of threads.
  const std::size_t edges = s_.edge_cam.size();
  chunk_points_ =
      std::max<std::size_t>(1024, edges == 0 ? np : (kEdgesPerSlot * nc * np + edges - 1) / edges);
  const std::size_t num_chunks = (np + chunk_points_ - 1) / chunk_points_;
  // Slots: per chunk, one partial diagonal block (dc x dc) and gradient (dc) per camera the
  // chunk's points are seen by, laid out chunk after chunk.
  edge_slot_.assign(s_.edge_cam.size(), 0);
  std::vector<std::vector<std::size_t>> slots_of_camera(nc);
  std::vector<std::size_t> slot_of_camera(nc, 0);
  std::vector<int> seen_in_chunk(nc, -1);
  std::size_t slot_size = 0;
  chunk_h_size_ = 0;
  chunk_b_size_ = 0;
  pt_contrib_h_local_.assign(s_.pt_contribs.size(), 0);
  pt_contrib_b_local_.assign(s_.pt_contribs.size(), 0);
  chunk_slot_begin_.assign(num_chunks + 1, 0);
  for (std::size_t k = 0; k < num_chunks; ++k) {
    const auto [p0, p1] = chunk_range(k);
    chunk_slot_begin_[k] = slot_size;
    for (std::size_t e = s_.pt_edge_begin[p0]; e < s_.pt_edge_begin[p1]; ++e) {
      const auto c = at(s_.edge_cam[e]);
      if (seen_in_chunk[c] != static_cast<int>(k)) {
        seen_in_chunk[c] = static_cast<int>(k);
        slot_of_camera[c] = slot_size;
        slots_of_camera[c].push_back(slot_size);
        slot_size += at(s_.cam_dim[c]) * at(s_.cam_dim[c] + 1);
      }
      edge_slot_[e] = slot_of_camera[c];
    }
    for (std::size_t j = 0; j < num_pieces(k); ++j) {  // a buffer per piece
      const auto [s0, s1] = piece_range(k, j);
      std::size_t h = 0, b = 0;
      for (std::size_t q = s_.pt_contrib_begin[s0]; q < s_.pt_contrib_begin[s1]; ++q) {
        const auto D = at(s_.block_dim(s_.pt_contribs[q].first));
        pt_contrib_h_local_[q] = h;
        pt_contrib_b_local_[q] = b;
        if (direct_[q]) {
          h += at(direct_rows_[q]) * (D + 1);  // Jacobian rows, then residuals
        } else {
          h += D * (D + 1) / 2;
          b += D;
        }
      }
      chunk_h_size_ = std::max(chunk_h_size_, h);
      chunk_b_size_ = std::max(chunk_b_size_, b);
    }
  }
  chunk_slot_begin_[num_chunks] = slot_size;
  // Standard chunks: every block a two-row direct block of one 9-camera and one 3-point, laid out
  // [camera, point] and the only contribution to its edge (scatter_standard_chunk_9_3()).
  chunk_standard_.assign(num_chunks, 0);
  for (std::size_t k = 0; k < num_chunks && s_.kernel == SchurKernel::kCamera9Point3; ++k) {
    bool standard = true;
    for (std::size_t j = 0; j < num_pieces(k) && standard; ++j) {
      const auto [s0, s1] = piece_range(k, j);
      const std::size_t q0 = s_.pt_contrib_begin[s0];
      standard = q0 < s_.pt_contrib_begin[s1];
      for (std::size_t q = q0; q < s_.pt_contrib_begin[s1] && standard; ++q) {
        const std::size_t e = direct_edge_[q];
        standard = direct_[q] && direct_rows_[q] == 2 &&
                   s_.block_dim(s_.pt_contribs[q].first) == 12 && s_.pt_contribs[q].second == 9 &&
                   direct_cam_local_[q] == 0 && e != kNoEdge && edge_assigned_[e] &&
                   pt_contrib_h_local_[q] == 26 * (q - q0);
      }
    }
    chunk_standard_[k] = standard ? 1 : 0;
  }
  slots_.assign(slot_size, 0.0);
  cam_slot_begin_.assign(nc + 1, 0);
  cam_slots_.clear();
  for (std::size_t c = 0; c < nc; ++c) {
    cam_slots_.insert(cam_slots_.end(), slots_of_camera[c].begin(), slots_of_camera[c].end());
    cam_slot_begin_[c + 1] = cam_slots_.size();
  }
}

/// Blocks without a point: linearized into other_, storage of their own.
void SchurLinearization::plan_other_blocks(const Problem& problem) {
  const auto blocks = problem.blocks();
  std::vector<char> has_point(blocks.size(), 0);
  for (const auto& [block, local] : s_.pt_contribs) has_point[static_cast<std::size_t>(block)] = 1;
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    if (!has_point[i]) other_blocks_.push_back(i);
  }
  // Indexed by block, and sized only when some block has no point (none has in a bundle
  // adjustment: nothing then reads other_).
  if (other_blocks_.empty()) return;
  other_.dim.assign(blocks.size(), 0);
  other_.h_offset.assign(blocks.size(), 0);
  other_.b_offset.assign(blocks.size(), 0);
  other_.cost.assign(blocks.size(), 0.0);
  std::size_t h = 0, b = 0;
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    const int D = s_.block_dims[i];
    other_.dim[i] = D;
    if (has_point[i]) continue;
    other_.h_offset[i] = h;
    other_.b_offset[i] = b;
    h += at(D) * at(D + 1) / 2;
    b += at(D);
  }
  other_.h.assign(h, 0.0);
  other_.b.assign(b, 0.0);
}

/// Zeroes the slots of chunk k (fused; they lie together).
void SchurLinearization::zero_slots(std::size_t k) {
  if (!s_.fused) return;
  std::fill(slots_.data() + chunk_slot_begin_[k], slots_.data() + chunk_slot_begin_[k + 1], 0.0);
}

/// Points [p0, p1) of chunk k (its slots zeroed before its first points).
template <int DC, int DP, typename HOf, typename BOf>
void SchurLinearization::scatter_chunk_sized(std::size_t k, std::size_t p0, std::size_t p1,
                                             double* gradient, const HOf& h_of, const BOf& b_of,
                                             bool use_direct) {
  if constexpr (DC == 9 && DP == 3) {
    if (use_direct && chunk_standard_[k]) {
      scatter_standard_chunk_9_3(p0, p1, s_.pt_contrib_begin.data(), direct_edge_.data(),
                                 s_.edge_w_offset.data(), edge_slot_.data(), s_.pt_v_offset.data(),
                                 s_.pt_offset.data(), h_of(s_.pt_contrib_begin[p0]),
                                 values_.v.data(), gradient, values_.w.data(), slots_.data());
      return;
    }
  }
  for (std::size_t p = p0; p < p1; ++p) {
    const int dp = DP > 0 ? DP : s_.pt_dim[p];
    double* V = values_.v.data() + s_.pt_v_offset[p];
    std::fill_n(V, at(dp) * at(dp), 0.0);
    double* g = gradient + s_.pt_offset[p];
    for (std::size_t e = s_.pt_edge_begin[p]; e < s_.pt_edge_begin[p + 1]; ++e) {
      if (use_direct && edge_assigned_[e]) continue;  // its one direct block writes W
      const int dc = DC > 0 ? DC : s_.cam_dim[at(s_.edge_cam[e])];
      std::fill_n(values_.w.data() + s_.edge_w_offset[e], at(dc) * at(dp), 0.0);
    }
    for (std::size_t q = s_.pt_contrib_begin[p]; q < s_.pt_contrib_begin[p + 1]; ++q) {
      const auto [block, local] = s_.pt_contribs[q];
      if (use_direct && direct_[q]) {
        const std::size_t e = direct_edge_[q];
        const bool has_camera = e != kNoEdge;
        const int dc = has_camera ? s_.cam_dim[at(s_.edge_cam[e])] : 0;
        const int n = direct_rows_[q];
        const int D = s_.block_dim(block);
        const double* J = h_of(q);
        const int cam_local = has_camera ? direct_cam_local_[q] : -1;
        double* W = has_camera ? values_.w.data() + s_.edge_w_offset[e] : nullptr;
        double* slot = has_camera ? slots_.data() + edge_slot_[e] : nullptr;
        const bool assign_w = has_camera && edge_assigned_[e];
        if constexpr (DC == 9 && DP == 3) {
          scatter_rows_9_3(J, J + n * D, n, D, local, cam_local, V, g, W, slot, assign_w);
        } else if constexpr (DC == 6 && DP == 3) {
          scatter_rows_6_3(J, J + n * D, n, D, local, cam_local, V, g, W, slot, assign_w);
        } else if (assign_w) {
          std::fill_n(W, at(dc) * at(dp), 0.0);
          scatter_rows<DC, DP>(J, J + n * D, n, D, local, cam_local, dc, dp, V, g, W, slot);
        } else {
          scatter_rows<DC, DP>(J, J + n * D, n, D, local, cam_local, dc, dp, V, g, W, slot);
        }
        continue;
      }
      add_packed_block<DP, DP>(h_of(q), at(s_.block_dim(block)), at(local), at(local), dp, dp, V,
                               at(dp));
      const double* b = b_of(q) + local;
      for (int r = 0; r < dp; ++r) g[r] += b[r];
    }
    for (std::size_t e = s_.pt_edge_begin[p]; e < s_.pt_edge_begin[p + 1]; ++e) {
      const int dc = s_.cam_dim[at(s_.edge_cam[e])];
      double* W = values_.w.data() + s_.edge_w_offset[e];
      for (std::size_t q = s_.edge_contrib_begin[e]; q < s_.edge_contrib_begin[e + 1]; ++q) {
        const SchurStructure::Contribution& src = s_.edge_contribs[q];
        if (use_direct && direct_[s_.edge_contrib_source[q]]) continue;
        const double* H = h_of(s_.edge_contrib_source[q]);
        const auto D = at(s_.block_dim(src.block));
        add_packed_block<DC, DP>(H, D, at(src.row_local), at(src.col_local), dc, dp, W, at(dc));
        if (!s_.fused) continue;
        double* slot = slots_.data() + edge_slot_[e];
        add_packed_block<DC, DC>(H, D, at(src.row_local), at(src.row_local), dc, dc, slot, at(dc));
        const double* b = b_of(s_.edge_contrib_source[q]) + src.row_local;
        double* slot_g = slot + at(dc) * at(dc);
        for (int r = 0; r < dc; ++r) slot_g[r] += b[r];
      }
    }
  }
}

template <typename HOf, typename BOf>
void SchurLinearization::scatter_chunk(std::size_t k, std::size_t p0, std::size_t p1,
                                       double* gradient, const HOf& h_of, const BOf& b_of,
                                       bool use_direct) {
  switch (s_.kernel) {
    case SchurKernel::kCamera9Point3:
      scatter_chunk_sized<9, 3>(k, p0, p1, gradient, h_of, b_of, use_direct);
      break;
    case SchurKernel::kCamera6Point3:
      scatter_chunk_sized<6, 3>(k, p0, p1, gradient, h_of, b_of, use_direct);
      break;
    case SchurKernel::kDynamic:
      scatter_chunk_sized<0, 0>(k, p0, p1, gradient, h_of, b_of, use_direct);
      break;
  }
}

/// The kept variables: A's blocks (pairs, from `blocks`), their gradients and, fused, the sums
/// of their slots in chunk order.
void SchurLinearization::gather_cameras(const BlockLinearizations& blocks, double* gradient) {
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, s_.cam_dim.size(), 4),
      [&](const tbb::blocked_range<std::size_t>& range) {
        for (std::size_t j = range.begin(); j != range.end(); ++j) {
          const int dj = s_.cam_dim[j];
          for (std::size_t k = s_.column_pair_begin[j]; k < s_.column_pair_begin[j + 1]; ++k) {
            const SchurStructure::Pair& pair = s_.pairs[k];
            const int di = s_.cam_dim[at(pair.row_cam)];
            double* out = values_.a.data() + pair.h_offset;
            std::fill_n(out, at(di) * at(dj), 0.0);
            for (std::size_t q = pair.contrib_begin; q < pair.contrib_end; ++q) {
              const SchurStructure::Contribution& src = s_.pair_contribs[q];
              const auto bi = static_cast<std::size_t>(src.block);
              add_packed_block(blocks.h.data() + blocks.h_offset[bi], at(blocks.dim[bi]),
                               at(src.row_local), at(src.col_local), di, dj, out, at(di));
            }
          }
          double* g = gradient + s_.cam_offset[j];
          for (std::size_t s = s_.cam_grad_begin[j]; s < s_.cam_grad_begin[j + 1]; ++s) {
            const auto [block, local] = s_.cam_grad[s];
            const double* b =
                blocks.b.data() + blocks.b_offset[static_cast<std::size_t>(block)] + local;
            for (int r = 0; r < dj; ++r) g[r] += b[r];
          }
          if (!s_.fused) continue;
          double* A =
              values_.a.data() + s_.pairs[s_.column_pair_begin[j]].h_offset;  // the diagonal block
          const std::size_t dd = at(dj) * at(dj);
          for (std::size_t s = cam_slot_begin_[j]; s < cam_slot_begin_[j + 1]; ++s) {
            // A slot's lower triangle holds the sum (its upper one may not): mirror it.
            const double* slot = slots_.data() + cam_slots_[s];
            for (int c = 0; c < dj; ++c) {
              A[at(c) * at(dj) + at(c)] += slot[at(c) * at(dj) + at(c)];
              for (int r = c + 1; r < dj; ++r) {
                const double v = slot[at(c) * at(dj) + at(r)];
                A[at(c) * at(dj) + at(r)] += v;
                A[at(r) * at(dj) + at(c)] += v;
              }
            }
            for (int r = 0; r < dj; ++r) g[r] += slot[dd + at(r)];
          }
        }
      });
}

void SchurLinearization::assemble(const BlockLinearizations& blocks, Eigen::VectorXd* gradient) {
  gradient->setZero(s_.n);
  double* g = gradient->data();
  const auto h_of = [&](std::size_t q) {
    return blocks.h.data() + blocks.h_offset[static_cast<std::size_t>(s_.pt_contribs[q].first)];
  };
  const auto b_of = [&](std::size_t q) {
    return blocks.b.data() + blocks.b_offset[static_cast<std::size_t>(s_.pt_contribs[q].first)];
  };
  const std::size_t num_chunks = num_point_chunks();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, num_chunks, 1),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t k = range.begin(); k != range.end(); ++k) {
                        zero_slots(k);
                        const auto [p0, p1] = chunk_range(k);
                        scatter_chunk(k, p0, p1, g, h_of, b_of, /*use_direct=*/false);
                      }
                    });
  gather_cameras(blocks, g);
}

LinearizeReport SchurLinearization::linearize(const BlockEvaluator& evaluator, int which,
                                              Eigen::VectorXd* gradient) {
  LinearizeReport report;
  Stopwatch wall;
  gradient->setZero(s_.n);
  double* g = gradient->data();
  const std::size_t num_blocks = s_.block_dims.size();
  std::atomic<std::size_t> first_bad{num_blocks};
  const std::size_t num_chunks = num_point_chunks();
  chunk_cost_.assign(num_chunks, 0.0);
  std::vector<double> evaluate_cpu(num_chunks, 0.0), scatter_cpu(num_chunks, 0.0);
  struct ChunkScratch {
    BlockScratch block;
    std::vector<double> h, b;
  };
  tbb::enumerable_thread_specific<ChunkScratch> scratch;
  // Points, a chunk at a time: evaluate the chunk's blocks into a small buffer that stays in
  // cache, then scatter them; no per-block storage for the whole problem.
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, num_chunks, 1),
      [&](const tbb::blocked_range<std::size_t>& range) {
        ChunkScratch& local = scratch.local();
        local.h.resize(chunk_h_size_);
        local.b.resize(chunk_b_size_);
        for (std::size_t k = range.begin(); k != range.end(); ++k) {
          Stopwatch t0;
          zero_slots(k);
          scatter_cpu[k] += t0.elapsed_s();
          double sum = 0.0;
          for (std::size_t j = 0; j < num_pieces(k); ++j) {
            t0.restart();
            const auto [s0, s1] = piece_range(k, j);
            for (std::size_t q = s_.pt_contrib_begin[s0]; q < s_.pt_contrib_begin[s1]; ++q) {
              const auto block = static_cast<std::size_t>(s_.pt_contribs[q].first);
              double c = 0.0;
              const bool ok =
                  direct_[q]
                      ? evaluator.evaluate_rows(block, which, direct_rows_[q],
                                                local.h.data() + pt_contrib_h_local_[q], &c)
                      : evaluator.evaluate_block(block, which, local.block,
                                                 local.h.data() + pt_contrib_h_local_[q],
                                                 local.b.data() + pt_contrib_b_local_[q], &c);
              if (!ok) record_bad_block(first_bad, block);
              sum += c;
            }
            evaluate_cpu[k] += t0.elapsed_s();
            t0.restart();
            scatter_chunk(
                k, s0, s1, g,
                [&](std::size_t q) { return local.h.data() + pt_contrib_h_local_[q]; },
                [&](std::size_t q) { return local.b.data() + pt_contrib_b_local_[q]; },
                /*use_direct=*/true);
            scatter_cpu[k] += t0.elapsed_s();
          }
          chunk_cost_[k] = sum;
        }
      });
  // Blocks without a point.
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, other_blocks_.size(), 8),
      [&](const tbb::blocked_range<std::size_t>& range) {
        BlockScratch& local = scratch.local().block;
        for (std::size_t k = range.begin(); k != range.end(); ++k) {
          const std::size_t i = other_blocks_[k];
          if (!evaluator.evaluate_block(i, which, local, other_.h.data() + other_.h_offset[i],
                                        other_.b.data() + other_.b_offset[i], &other_.cost[i])) {
            record_bad_block(first_bad, i);
          }
        }
      });
  const double evaluated_s = wall.elapsed_s();
  const std::size_t bad = first_bad.load();
  if (bad < num_blocks) {
    report.time.linearize_s = evaluated_s;
    report.error = evaluator.describe_bad_block(bad, which);
    return report;
  }
  wall.restart();
  gather_cameras(other_, g);
  const double gathered_s = wall.elapsed_s();
  // The chunk pass did both; split its wall time by the CPU time of each part.
  double evaluate_total = 0.0, scatter_total = 0.0;
  for (std::size_t k = 0; k < num_chunks; ++k) {
    evaluate_total += evaluate_cpu[k];
    scatter_total += scatter_cpu[k];
  }
  const double scatter_share =
      evaluate_total + scatter_total > 0.0 ? scatter_total / (evaluate_total + scatter_total) : 0.0;
  report.time.linearize_s = evaluated_s * (1.0 - scatter_share);
  report.time.assembly_s = evaluated_s * scatter_share + gathered_s;
  double total = 0.0;
  for (const double c : chunk_cost_) total += c;
  for (const std::size_t i : other_blocks_) total += other_.cost[i];
  report.cost = total;
  report.ok = true;
  return report;
}

}  // namespace carat::internal
