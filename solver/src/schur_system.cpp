#include "schur_system.hpp"

#include <cholmod.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <string>
#include <tuple>

#include "carat/base/error.hpp"
#include "carat/base/multiversion.hpp"
#include "carat/base/stopwatch.hpp"

namespace carat::internal {
namespace {

template <int R, int C>
using MapMatrix = Eigen::Map<Eigen::Matrix<double, R, C>>;
template <int R, int C>
using ConstMapMatrix = Eigen::Map<const Eigen::Matrix<double, R, C>>;
template <int R>
using MapVector = Eigen::Map<Eigen::Matrix<double, R, 1>>;
template <int R>
using ConstMapVector = Eigen::Map<const Eigen::Matrix<double, R, 1>>;

std::size_t at(int k) { return static_cast<std::size_t>(k); }

}  // namespace

SchurSystem::~SchurSystem() = default;

SchurSystem::SchurSystem(const Problem& problem, const std::vector<char>& eliminate,
                         Ordering ordering)
    : cholmod_(std::make_unique<CholmodSession>()) {
  const int num_vars = problem.num_variables();
  var_offset_.assign(at(num_vars), -1);
  std::vector<int> cam_of(at(num_vars), -1), pt_of(at(num_vars), -1), dim(at(num_vars), 0);
  for (int v = 0; v < num_vars; ++v) {
    const VariableId id{v};
    dim[at(v)] = problem.manifold(id).tangent_size();
    if (problem.is_constant(id)) continue;
    if (eliminate[at(v)]) {
      pt_of[at(v)] = static_cast<int>(pt_dim_.size());
      pt_dim_.push_back(dim[at(v)]);
    } else {
      cam_of[at(v)] = static_cast<int>(cam_dim_.size());
      cam_offset_.push_back(ns_);
      cam_dim_.push_back(dim[at(v)]);
      var_offset_[at(v)] = ns_;
      ns_ += dim[at(v)];
    }
  }
  n_ = ns_;
  std::size_t v_size = 0;
  for (int v = 0; v < num_vars; ++v) {
    const int p = pt_of[at(v)];
    if (p < 0) continue;
    var_offset_[at(v)] = n_;
    pt_offset_.push_back(n_);
    pt_v_offset_.push_back(v_size);
    n_ += dim[at(v)];
    v_size += at(dim[at(v)]) * at(dim[at(v)]);
  }
  const std::size_t nc = cam_dim_.size();
  const std::size_t np = pt_dim_.size();

  // Fixed-size kernels when every camera and every point have the same common dimension.
  const auto all_equal = [](const std::vector<int>& dims, int d) {
    return std::all_of(dims.begin(), dims.end(), [d](int x) { return x == d; });
  };
  if (all_equal(pt_dim_, 3) && all_equal(cam_dim_, 9)) kernel_ = 1;
  if (all_equal(pt_dim_, 3) && all_equal(cam_dim_, 6)) kernel_ = 2;

  // What each block touches.
  struct RawPair {
    int col, row;
    std::int32_t block;
    std::int16_t row_local, col_local;
  };
  struct RawEdge {
    int pt, cam;
    std::int32_t block;
    std::int16_t cam_local, pt_local;
  };
  std::vector<RawPair> raw_pairs;
  std::vector<RawEdge> raw_edges;
  std::vector<std::tuple<int, std::int32_t, std::int16_t>> raw_pt, raw_cam;
  const auto blocks = problem.blocks();
  raw_cam.reserve(blocks.size());
  raw_edges.reserve(blocks.size());
  raw_pt.reserve(blocks.size());
  std::vector<std::pair<int, int>> cams;  // (camera, local) of one block
  std::vector<char> block_has_point(blocks.size(), 0);
  for (const auto& entry : blocks) block_dims_.push_back(entry.block->tangent_dim());
  fused_ = true;
  for (std::size_t bi = 0; bi < blocks.size(); ++bi) {
    cams.clear();
    int point = -1;
    int point_local = 0;
    int local = 0;
    for (VariableId v : blocks[bi].variables) {
      const int c = cam_of[at(v.index)];
      const int p = pt_of[at(v.index)];
      if (c >= 0) cams.emplace_back(c, local);
      if (p >= 0) {
        if (point >= 0) {
          throw Error("Schur complement: residual block " + std::to_string(bi) +
                      " connects two eliminated variables");
        }
        point = p;
        point_local = local;
      }
      local += dim[at(v.index)];
    }
    const auto block = static_cast<std::int32_t>(bi);
    for (const auto& [ca, la] : cams) {
      raw_cam.emplace_back(ca, block, static_cast<std::int16_t>(la));
      for (const auto& [cb, lb] : cams) {
        if (ca < cb) continue;
        raw_pairs.push_back(
            {cb, ca, block, static_cast<std::int16_t>(la), static_cast<std::int16_t>(lb)});
      }
      if (point >= 0) {
        raw_edges.push_back({point, ca, block, static_cast<std::int16_t>(la),
                             static_cast<std::int16_t>(point_local)});
      }
    }
    if (point >= 0) {
      raw_pt.emplace_back(point, block, static_cast<std::int16_t>(point_local));
      block_has_point[bi] = 1;
      if (cams.size() > 1) fused_ = false;
    }
  }
  // Fused: the kept-variable part of a block with a point is one diagonal block (of its one
  // camera), summed per chunk of points (slots below) rather than gathered per camera.
  if (fused_) {
    const auto has_point = [&](std::int32_t block) {
      return block_has_point[static_cast<std::size_t>(block)] != 0;
    };
    std::erase_if(raw_cam, [&](const auto& entry) { return has_point(std::get<1>(entry)); });
    std::erase_if(raw_pairs, [&](const RawPair& pair) { return has_point(pair.block); });
  }

  // Edges, point-major, and their contributions.
  // By point (a stable counting sort: blocks stay in order within a point), then by camera.
  {
    std::vector<std::size_t> start(np + 1, 0);
    for (const RawEdge& r : raw_edges) ++start[at(r.pt) + 1];
    for (std::size_t p = 0; p < np; ++p) start[p + 1] += start[p];
    std::vector<RawEdge> by_point(raw_edges.size());
    for (const RawEdge& r : raw_edges) by_point[start[at(r.pt)]++] = r;
    raw_edges.swap(by_point);
    for (std::size_t b = 0, p = 0; p < np; ++p) {
      const std::size_t e = start[p];
      std::sort(raw_edges.begin() + static_cast<std::ptrdiff_t>(b),
                raw_edges.begin() + static_cast<std::ptrdiff_t>(e),
                [](const RawEdge& x, const RawEdge& y) {
                  return std::tie(x.cam, x.block) < std::tie(y.cam, y.block);
                });
      b = e;
    }
  }
  pt_edge_begin_.assign(np + 1, 0);
  std::size_t w_size = 0;
  for (std::size_t k = 0; k < raw_edges.size();) {
    const RawEdge& first = raw_edges[k];
    edge_cam_.push_back(first.cam);
    edge_pt_.push_back(first.pt);
    edge_w_offset_.push_back(w_size);
    w_size += at(cam_dim_[at(first.cam)]) * at(pt_dim_[at(first.pt)]);
    edge_contrib_begin_.push_back(edge_contribs_.size());
    for (; k < raw_edges.size() && raw_edges[k].pt == first.pt && raw_edges[k].cam == first.cam;
         ++k) {
      edge_contribs_.push_back({raw_edges[k].block, raw_edges[k].cam_local, raw_edges[k].pt_local});
    }
    pt_edge_begin_[at(first.pt) + 1] = edge_cam_.size();
  }
  edge_contrib_begin_.push_back(edge_contribs_.size());
  for (std::size_t p = 1; p <= np; ++p)
    pt_edge_begin_[p] = std::max(pt_edge_begin_[p], pt_edge_begin_[p - 1]);
  raw_edges = {};
  const std::size_t num_edges = edge_cam_.size();

  // Each camera's edges in point order.
  cam_edge_begin_.assign(nc + 1, 0);
  for (std::size_t e = 0; e < num_edges; ++e) ++cam_edge_begin_[at(edge_cam_[e]) + 1];
  for (std::size_t c = 0; c < nc; ++c) cam_edge_begin_[c + 1] += cam_edge_begin_[c];
  cam_edges_.resize(num_edges);
  {
    std::vector<std::size_t> fill(cam_edge_begin_.begin(), cam_edge_begin_.end() - 1);
    for (std::size_t e = 0; e < num_edges; ++e) cam_edges_[fill[at(edge_cam_[e])]++] = e;
  }

  // Points' V and gradient contributions; cameras' gradient contributions.
  // By point, blocks ascending: raw_pt is in block order, so a stable counting sort by point.
  pt_contrib_begin_.assign(np + 1, 0);
  for (const auto& [p, block, local] : raw_pt) ++pt_contrib_begin_[at(p) + 1];
  for (std::size_t p = 0; p < np; ++p) pt_contrib_begin_[p + 1] += pt_contrib_begin_[p];
  pt_contribs_.resize(raw_pt.size());
  {
    std::vector<std::size_t> fill(pt_contrib_begin_.begin(), pt_contrib_begin_.end() - 1);
    for (const auto& [p, block, local] : raw_pt) pt_contribs_[fill[at(p)]++] = {block, local};
  }
  // Where each block with a point sits in pt_contribs_ (its source index).
  std::vector<std::uint32_t> block_source(blocks.size(), 0);
  for (std::size_t k = 0; k < pt_contribs_.size(); ++k) {
    block_source[static_cast<std::size_t>(pt_contribs_[k].first)] = static_cast<std::uint32_t>(k);
  }
  edge_contrib_source_.resize(edge_contribs_.size());
  for (std::size_t q = 0; q < edge_contribs_.size(); ++q) {
    edge_contrib_source_[q] = block_source[static_cast<std::size_t>(edge_contribs_[q].block)];
  }
  if (fused_) plan_chunks(problem);
  // By camera, blocks ascending (raw_cam is in block order, one entry per block and camera).
  cam_grad_begin_.assign(nc + 1, 0);
  for (const auto& [c, block, local] : raw_cam) ++cam_grad_begin_[at(c) + 1];
  for (std::size_t c = 0; c < nc; ++c) cam_grad_begin_[c + 1] += cam_grad_begin_[c];
  cam_grad_.resize(raw_cam.size());
  {
    std::vector<std::size_t> fill(cam_grad_begin_.begin(), cam_grad_begin_.end() - 1);
    for (const auto& [c, block, local] : raw_cam) cam_grad_[fill[at(c)]++] = {block, local};
  }

  // Camera pairs of S: every diagonal, pairs inside blocks, pairs of cameras sharing a point.
  // Per column camera j, the row cameras i >= j it pairs with: a marker per camera avoids
  // sorting every shared-point pair (Sum over points of k (k + 1) / 2 of them).
  std::vector<std::uint64_t> keys;  // column << 32 | row, ascending
  const auto key = [](int col, int row) {
    return (static_cast<std::uint64_t>(col) << 32) | static_cast<std::uint32_t>(row);
  };
  {
    std::vector<std::vector<int>> block_rows(nc);
    for (const RawPair& r : raw_pairs) block_rows[at(r.col)].push_back(r.row);
    std::vector<std::size_t> marked(nc, nc);  // column that last marked camera i
    std::vector<int> rows;
    for (std::size_t j = 0; j < nc; ++j) {
      rows.clear();
      const auto mark = [&](int i) {
        if (marked[at(i)] != j) {
          marked[at(i)] = j;
          rows.push_back(i);
        }
      };
      mark(static_cast<int>(j));
      for (const int i : block_rows[j]) mark(i);
      for (std::size_t k = cam_edge_begin_[j]; k < cam_edge_begin_[j + 1]; ++k) {
        const std::size_t e = cam_edges_[k];
        for (std::size_t f = e; f < pt_edge_begin_[at(edge_pt_[e]) + 1]; ++f) mark(edge_cam_[f]);
      }
      std::sort(rows.begin(), rows.end());
      for (const int i : rows) keys.push_back(key(static_cast<int>(j), i));
    }
  }
  const auto pair_index = [&](int col, int row) {
    return static_cast<std::size_t>(std::lower_bound(keys.begin(), keys.end(), key(col, row)) -
                                    keys.begin());
  };
  pairs_.resize(keys.size());
  column_pair_begin_.assign(nc + 1, 0);
  std::size_t a_size = 0;
  for (std::size_t k = 0; k < keys.size(); ++k) {
    const auto col = static_cast<int>(keys[k] >> 32);
    const auto row = static_cast<int>(keys[k] & 0xffffffffu);
    pairs_[k].row_cam = row;
    pairs_[k].h_offset = a_size;
    a_size += at(cam_dim_[at(row)]) * at(cam_dim_[at(col)]);
    ++column_pair_begin_[at(col) + 1];
  }
  for (std::size_t c = 0; c < nc; ++c) column_pair_begin_[c + 1] += column_pair_begin_[c];

  // A's contributions per pair (block order) and the shared-point products per pair (point
  // order): counting sorts keep both orders fixed.
  std::sort(raw_pairs.begin(), raw_pairs.end(), [](const RawPair& x, const RawPair& y) {
    return std::tie(x.col, x.row, x.block) < std::tie(y.col, y.row, y.block);
  });
  {
    std::vector<std::size_t> count(keys.size() + 1, 0);
    std::vector<std::size_t> pair_of(raw_pairs.size());
    for (std::size_t k = 0; k < raw_pairs.size(); ++k) {
      pair_of[k] = pair_index(raw_pairs[k].col, raw_pairs[k].row);
      ++count[pair_of[k] + 1];
    }
    for (std::size_t k = 0; k < keys.size(); ++k) count[k + 1] += count[k];
    pair_contribs_.resize(raw_pairs.size());
    for (std::size_t k = 0; k < keys.size(); ++k) {
      pairs_[k].contrib_begin = count[k];
      pairs_[k].contrib_end = count[k + 1];
    }
    for (std::size_t k = 0; k < raw_pairs.size(); ++k) {
      pair_contribs_[count[pair_of[k]]++] = {raw_pairs[k].block, raw_pairs[k].row_local,
                                             raw_pairs[k].col_local};
    }
  }
  raw_pairs = {};
  // Groups of kGroupCameras consecutive cameras for form_reduced_system(): the points each
  // group sees (ascending) and the values of its stacked columns of S blocks.
  {
    const std::size_t num_groups = (nc + kGroupCameras - 1) / kGroupCameras;
    group_points_begin_.assign(num_groups + 1, 0);
    std::vector<std::size_t> seen(np, num_groups);  // group that last listed point p
    for (std::size_t group = 0; group < num_groups; ++group) {
      const std::size_t first = group_points_.size();
      std::size_t values = 0;
      for (std::size_t j = group * kGroupCameras; j < std::min(nc, (group + 1) * kGroupCameras);
           ++j) {
        for (std::size_t k = cam_edge_begin_[j]; k < cam_edge_begin_[j + 1]; ++k) {
          const auto p = at(edge_pt_[cam_edges_[k]]);
          if (seen[p] != group) {
            seen[p] = group;
            group_points_.push_back(p);
          }
        }
        for (std::size_t k = column_pair_begin_[j]; k < column_pair_begin_[j + 1]; ++k) {
          values += at(cam_dim_[at(pairs_[k].row_cam)]) * at(cam_dim_[j]);
        }
      }
      std::sort(group_points_.begin() + static_cast<std::ptrdiff_t>(first), group_points_.end());
      for (std::size_t k = first; k < group_points_.size(); ++k) {
        const std::size_t p = group_points_[k];
        std::size_t size = 0;
        for (std::size_t e = pt_edge_begin_[p]; e < pt_edge_begin_[p + 1]; ++e) {
          size += at(cam_dim_[at(edge_cam_[e])]) * at(pt_dim_[p]);
        }
        max_point_y_ = std::max(max_point_y_, size);
      }
      group_points_begin_[group + 1] = group_points_.size();
      max_group_values_ = std::max(max_group_values_, values);
    }
  }

  // Lower-triangular CSC of S in camera order: per scalar column of camera j, the diagonal
  // block's rows from the diagonal down, then the blocks of the cameras below it.
  colptr_.assign(at(ns_) + 1, 0);
  for (std::size_t j = 0; j < nc; ++j) {
    const int dj = cam_dim_[j];
    std::int64_t below = 0;
    for (std::size_t k = column_pair_begin_[j]; k < column_pair_begin_[j + 1]; ++k) {
      if (at(pairs_[k].row_cam) == j) continue;
      pairs_[k].row_in_column = below;
      below += cam_dim_[at(pairs_[k].row_cam)];
    }
    for (int c = 0; c < dj; ++c) {
      const std::size_t col = at(cam_offset_[j] + c);
      colptr_[col + 1] = colptr_[col] + (dj - c) + below;
    }
  }
  rows_.assign(static_cast<std::size_t>(colptr_.back()), 0);
  for (std::size_t j = 0; j < nc; ++j) {
    const int dj = cam_dim_[j];
    for (int c = 0; c < dj; ++c) {
      auto pos = static_cast<std::size_t>(colptr_[at(cam_offset_[j] + c)]);
      for (int r = c; r < dj; ++r) rows_[pos++] = cam_offset_[j] + r;
      for (std::size_t k = column_pair_begin_[j]; k < column_pair_begin_[j + 1]; ++k) {
        const auto i = at(pairs_[k].row_cam);
        if (i == j) continue;
        for (int r = 0; r < cam_dim_[i]; ++r) rows_[pos++] = cam_offset_[i] + r;
      }
    }
  }
  values_.assign(rows_.size(), 0.0);
  // The assembled values are zeroed here, as SparseSystem zeroes its matrix: their pages are
  // first touched while the system is set up, not in the first assembly.
  a_.assign(a_size, 0.0);
  w_.assign(w_size, 0.0);
  v_.assign(v_size, 0.0);
  l_inverse_.assign(v_size, 0.0);
  z_.assign(at(n_ - ns_), 0.0);

  cholmod_common& common = cholmod_->common();
  std::string ordering_name = "none";
  if (ns_ > 0) {
    cholmod_->set_lower_matrix(at(ns_), colptr_.data(), rows_.data(), values_.data(), rows_.size());
    common.supernodal = CHOLMOD_SUPERNODAL;
    if (ordering == Ordering::kAmd) {
      common.nmethods = 1;
      common.method[0].ordering = CHOLMOD_AMD;
    } else if (ordering == Ordering::kMetis) {
      common.nmethods = 1;
      common.method[0].ordering = CHOLMOD_METIS;
    } else {
      common.nmethods = 2;  // the one whose factor needs fewer flops wins
      common.method[0].ordering = CHOLMOD_AMD;
      common.method[1].ordering = CHOLMOD_METIS;
    }
    cholmod_->analyze("Schur complement");
    const int selected = common.method[common.selected].ordering;
    ordering_name = selected == CHOLMOD_METIS ? "METIS" : "AMD";
    factor_nnz_ = static_cast<std::size_t>(common.lnz);
  }
  description_ = "schur complement of " + std::to_string(np) + " eliminated variables, " +
                 "cholmod supernodal on the reduced system (" + std::to_string(ns_) + " x " +
                 std::to_string(ns_) + ", " + ordering_name + " ordering)";
}

void SchurSystem::plan_chunks(const Problem& problem) {
  const std::size_t np = pt_dim_.size();
  const std::size_t nc = cam_dim_.size();
  const auto blocks = problem.blocks();
  // Points per chunk: enough that a chunk's edges are many per camera it touches (about
  // kEdgesPerSlot for each camera of the problem), so that its slots are few beside its blocks; at
  // least 1024. (The chunk is evaluated and scattered a piece of points at a time, so its size
  // does not set the buffer's.) A function of the problem alone, so results do not depend on the
  // number of threads.
  const std::size_t edges = edge_cam_.size();
  chunk_points_ =
      std::max<std::size_t>(1024, edges == 0 ? np : (kEdgesPerSlot * nc * np + edges - 1) / edges);
  const std::size_t num_chunks = (np + chunk_points_ - 1) / chunk_points_;
  // Slots: per chunk, one partial diagonal block (dc x dc) and gradient (dc) per camera the
  // chunk's points are seen by, laid out chunk after chunk.
  edge_slot_.assign(edge_cam_.size(), 0);
  std::vector<std::vector<std::size_t>> slots_of_camera(nc);
  std::vector<std::size_t> slot_of_camera(nc, 0);
  std::vector<int> seen_in_chunk(nc, -1);
  std::size_t slot_size = 0;
  chunk_h_size_ = 0;
  chunk_b_size_ = 0;
  pt_contrib_h_local_.assign(pt_contribs_.size(), 0);
  pt_contrib_b_local_.assign(pt_contribs_.size(), 0);
  // Direct: a block of a few rows, no loss and no reduced form is scattered from its Jacobian
  // rows (J_p^T J_p into V, J_c^T J_p into W, J_c^T J_c into its camera's slot), without its
  // D x D H. Its camera (if any) is the row variable of its one edge contribution.
  direct_.assign(pt_contribs_.size(), 0);
  direct_rows_.assign(pt_contribs_.size(), 0);
  direct_cam_local_.assign(pt_contribs_.size(), -1);
  direct_edge_.assign(pt_contribs_.size(), kNoEdge);
  for (std::size_t e = 0; e < edge_cam_.size(); ++e) {
    for (std::size_t q = edge_contrib_begin_[e]; q < edge_contrib_begin_[e + 1]; ++q) {
      direct_edge_[edge_contrib_source_[q]] = e;
      direct_cam_local_[edge_contrib_source_[q]] = edge_contribs_[q].row_local;
    }
  }
  for (std::size_t q = 0; q < pt_contribs_.size(); ++q) {
    const auto& entry = blocks[static_cast<std::size_t>(pt_contribs_[q].first)];
    direct_rows_[q] = entry.block->num_rows();
    direct_[q] = !entry.loss && entry.block->num_rows() <= kDirectRows &&
                 entry.block->reduced_dim() == block_dim(pt_contribs_[q].first);
  }
  edge_assigned_.assign(edge_cam_.size(), 0);
  for (std::size_t e = 0; e < edge_cam_.size(); ++e) {
    edge_assigned_[e] = edge_contrib_begin_[e + 1] == edge_contrib_begin_[e] + 1 &&
                        direct_[edge_contrib_source_[edge_contrib_begin_[e]]];
  }
  chunk_slot_begin_.assign(num_chunks + 1, 0);
  for (std::size_t k = 0; k < num_chunks; ++k) {
    const auto [p0, p1] = chunk_range(k);
    chunk_slot_begin_[k] = slot_size;
    for (std::size_t e = pt_edge_begin_[p0]; e < pt_edge_begin_[p1]; ++e) {
      const auto c = at(edge_cam_[e]);
      if (seen_in_chunk[c] != static_cast<int>(k)) {
        seen_in_chunk[c] = static_cast<int>(k);
        slot_of_camera[c] = slot_size;
        slots_of_camera[c].push_back(slot_size);
        slot_size += at(cam_dim_[c]) * at(cam_dim_[c] + 1);
      }
      edge_slot_[e] = slot_of_camera[c];
    }
    for (std::size_t j = 0; j < num_pieces(k); ++j) {  // a buffer per piece
      const auto [s0, s1] = piece_range(k, j);
      std::size_t h = 0, b = 0;
      for (std::size_t q = pt_contrib_begin_[s0]; q < pt_contrib_begin_[s1]; ++q) {
        const auto D = at(block_dim(pt_contribs_[q].first));
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
  for (std::size_t k = 0; k < num_chunks && kernel_ == 1; ++k) {
    bool standard = true;
    for (std::size_t j = 0; j < num_pieces(k) && standard; ++j) {
      const auto [s0, s1] = piece_range(k, j);
      const std::size_t q0 = pt_contrib_begin_[s0];
      standard = q0 < pt_contrib_begin_[s1];
      for (std::size_t q = q0; q < pt_contrib_begin_[s1] && standard; ++q) {
        const std::size_t e = direct_edge_[q];
        standard = direct_[q] && direct_rows_[q] == 2 && block_dim(pt_contribs_[q].first) == 12 &&
                   pt_contribs_[q].second == 9 && direct_cam_local_[q] == 0 && e != kNoEdge &&
                   edge_assigned_[e] && pt_contrib_h_local_[q] == 26 * (q - q0);
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
  // Blocks without a point: linearized into storage_ of their own.
  std::vector<char> has_point(blocks.size(), 0);
  for (const auto& [block, local] : pt_contribs_) has_point[static_cast<std::size_t>(block)] = 1;
  storage_.dim.assign(blocks.size(), 0);
  storage_.h_offset.assign(blocks.size(), 0);
  storage_.b_offset.assign(blocks.size(), 0);
  storage_.cost.assign(blocks.size(), 0.0);
  std::size_t h = 0, b = 0;
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    const int D = block_dims_[i];
    storage_.dim[i] = D;
    if (has_point[i]) continue;
    other_blocks_.push_back(i);
    storage_.h_offset[i] = h;
    storage_.b_offset[i] = b;
    h += at(D) * at(D + 1) / 2;
    b += at(D);
  }
  storage_.h.assign(h, 0.0);
  storage_.b.assign(b, 0.0);
}

/// The points of chunk k: V, their gradients, W per edge and, fused, the chunk's slots.
/// h_of(q) / b_of(q): packed H and b of the block of pt_contribs_[q].
/// The contributions of a direct block (see plan_chunks()) from its n Jacobian rows J (n x D,
/// row-major) and residuals r: V += J_p^T J_p, g_p += J_p^T r and, with a camera, W += J_c^T J_p
/// (W = J_c^T J_p with kAssignW: the edge's only contribution, W not zeroed first), the lower
/// triangle of slot += J_c^T J_c, slot gradient += J_c^T r. Each output element sums over the
/// rows first and touches memory once.
template <int DC, int DP, int N = 0, bool kAssignW = false>
__attribute__((always_inline)) inline void scatter_rows(const double* __restrict J,
                                                        const double* __restrict r, int rows, int D,
                                                        int pt_local, int cam_local, int dc, int dp,
                                                        double* __restrict V, double* __restrict g,
                                                        double* __restrict W,
                                                        double* __restrict slot) {
  const int C = DC > 0 ? DC : dc;
  const int P = DP > 0 ? DP : dp;
  const int n = N > 0 ? N : rows;
  const auto row = [&](int k) { return J + k * D; };
  for (int b = 0; b < P; ++b) {
    for (int a = 0; a < P; ++a) {
      double sum = 0.0;
      for (int k = 0; k < n; ++k) sum += row(k)[pt_local + a] * row(k)[pt_local + b];
      V[b * P + a] += sum;
    }
    double sum = 0.0;
    for (int k = 0; k < n; ++k) sum += row(k)[pt_local + b] * r[k];
    g[b] += sum;
  }
  if (cam_local < 0) return;
  for (int b = 0; b < P; ++b) {
    for (int a = 0; a < C; ++a) {
      double sum = 0.0;
      for (int k = 0; k < n; ++k) sum += row(k)[cam_local + a] * row(k)[pt_local + b];
      if constexpr (kAssignW) {
        W[b * C + a] = sum;
      } else {
        W[b * C + a] += sum;
      }
    }
  }
  for (int b = 0; b < C; ++b) {  // the lower triangle (gather_cameras() mirrors it)
    for (int a = b; a < C; ++a) {
      double sum = 0.0;
      for (int k = 0; k < n; ++k) sum += row(k)[cam_local + a] * row(k)[cam_local + b];
      slot[b * C + a] += sum;
    }
  }
  double* slot_g = slot + C * C;
  for (int a = 0; a < C; ++a) {
    double sum = 0.0;
    for (int k = 0; k < n; ++k) sum += row(k)[cam_local + a] * r[k];
    slot_g[a] += sum;
  }
}

// The helpers below pass 32-byte vectors by value; they are always inlined into the kernels
// (never called across a translation unit), so the compilers' note on the AVX calling convention
// does not apply.
#if defined(__clang__)
#pragma clang diagnostic push
#pragma clang diagnostic ignored "-Wpsabi"
#elif defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"
#endif

/// Four doubles as one vector (GCC / Clang vector extension; unaligned loads and stores).
using Double4 = double __attribute__((vector_size(32), aligned(8)));

__attribute__((always_inline)) inline Double4 load4(const double* p) {
  Double4 v;
  std::memcpy(&v, p, sizeof(v));
  return v;
}
__attribute__((always_inline)) inline void store4(double* p, Double4 v) {
  std::memcpy(p, &v, sizeof(v));
}

/// column[0, 9) (+)= x0 * y0 + x1 * y1, x0 / x1 two 9-vectors held as two Double4 and a tail.
template <bool kAssign>
__attribute__((always_inline)) inline void update_column_9(double* __restrict column,
                                                           const Double4 (&x0)[2], double x0_8,
                                                           const Double4 (&x1)[2], double x1_8,
                                                           double y0, double y1) {
  for (int h = 0; h < 2; ++h) {
    const Double4 sum = x0[h] * y0 + x1[h] * y1;
    store4(column + 4 * h, kAssign ? sum : load4(column + 4 * h) + sum);
  }
  const double tail = x0_8 * y0 + x1_8 * y1;
  column[8] = kAssign ? tail : column[8] + tail;
}

/// scatter_rows<9, 3, 2> for the common layout: two rows of 12 columns, the camera's 9 first,
/// the point's 3 last. The slot's whole 9 x 9 block is summed (whole columns vectorize; its
/// upper triangle is not read).
template <bool kAssignW>
__attribute__((always_inline)) inline void scatter_two_rows_9_3(
    const double* __restrict J, const double* __restrict r, double* __restrict V,
    double* __restrict g, double* __restrict W, double* __restrict slot) {
  const double* j0 = J;
  const double* j1 = J + 12;
  const double* p0 = j0 + 9;
  const double* p1 = j1 + 9;
  for (int b = 0; b < 3; ++b) {
    for (int a = 0; a < 3; ++a) V[b * 3 + a] += p0[a] * p0[b] + p1[a] * p1[b];
    g[b] += p0[b] * r[0] + p1[b] * r[1];
  }
  const Double4 c0[2] = {load4(j0), load4(j0 + 4)};
  const Double4 c1[2] = {load4(j1), load4(j1 + 4)};
  for (int b = 0; b < 3; ++b) {
    update_column_9<kAssignW>(W + b * 9, c0, j0[8], c1, j1[8], p0[b], p1[b]);
  }
  for (int b = 0; b < 9; ++b) {
    update_column_9<false>(slot + b * 9, c0, j0[8], c1, j1[8], j0[b], j1[b]);
  }
  update_column_9<false>(slot + 81, c0, j0[8], c1, j1[8], r[0], r[1]);
}

#if defined(__clang__)
#pragma clang diagnostic pop
#elif defined(__GNUC__)
#pragma GCC diagnostic pop
#endif

CARAT_MULTIVERSION void scatter_rows_9_3(const double* J, const double* r, int n, int D,
                                         int pt_local, int cam_local, double* V, double* g,
                                         double* W, double* slot, bool assign_w) {
  if (n == 2 && D == 12 && cam_local == 0 && pt_local == 9) {
    if (assign_w) {
      scatter_two_rows_9_3<true>(J, r, V, g, W, slot);
    } else {
      scatter_two_rows_9_3<false>(J, r, V, g, W, slot);
    }
  } else if (n == 2 && assign_w) {
    scatter_rows<9, 3, 2, true>(J, r, n, D, pt_local, cam_local, 9, 3, V, g, W, slot);
  } else if (n == 2) {
    scatter_rows<9, 3, 2>(J, r, n, D, pt_local, cam_local, 9, 3, V, g, W, slot);
  } else if (assign_w) {
    scatter_rows<9, 3, 0, true>(J, r, n, D, pt_local, cam_local, 9, 3, V, g, W, slot);
  } else {
    scatter_rows<9, 3>(J, r, n, D, pt_local, cam_local, 9, 3, V, g, W, slot);
  }
}
/// The points [p0, p1) of a standard chunk (see SchurSystem::plan_chunks()): per point, V zeroed,
/// then each block q of it (rows at J + 26 (q - q_begin[p0])) scattered by scatter_two_rows_9_3
/// into V, the point's gradient, its edge's W and its edge's slot.
CARAT_MULTIVERSION void scatter_standard_chunk_9_3(
    std::size_t p0, std::size_t p1, const std::size_t* q_begin, const std::size_t* edge_of_q,
    const std::size_t* w_offset, const std::size_t* slot_of_edge, const std::size_t* v_offset,
    const int* pt_offset, const double* J, double* v, double* gradient, double* w, double* slots) {
  const std::size_t q0 = q_begin[p0];
  for (std::size_t p = p0; p < p1; ++p) {
    double* V = v + v_offset[p];
    for (int a = 0; a < 9; ++a) V[a] = 0.0;
    double* g = gradient + pt_offset[p];
    for (std::size_t q = q_begin[p]; q < q_begin[p + 1]; ++q) {
      const std::size_t e = edge_of_q[q];
      const double* rows = J + 26 * (q - q0);
      scatter_two_rows_9_3<true>(rows, rows + 24, V, g, w + w_offset[e], slots + slot_of_edge[e]);
    }
  }
}

CARAT_MULTIVERSION void scatter_rows_6_3(const double* J, const double* r, int n, int D,
                                         int pt_local, int cam_local, double* V, double* g,
                                         double* W, double* slot, bool assign_w) {
  if (n == 2 && assign_w) {
    scatter_rows<6, 3, 2, true>(J, r, n, D, pt_local, cam_local, 6, 3, V, g, W, slot);
  } else if (n == 2) {
    scatter_rows<6, 3, 2>(J, r, n, D, pt_local, cam_local, 6, 3, V, g, W, slot);
  } else if (assign_w) {
    scatter_rows<6, 3, 0, true>(J, r, n, D, pt_local, cam_local, 6, 3, V, g, W, slot);
  } else {
    scatter_rows<6, 3>(J, r, n, D, pt_local, cam_local, 6, 3, V, g, W, slot);
  }
}

/// Zeroes the slots of chunk k (fused; they lie together).
void SchurSystem::zero_slots(std::size_t k) {
  if (!fused_) return;
  std::fill(slots_.data() + chunk_slot_begin_[k], slots_.data() + chunk_slot_begin_[k + 1], 0.0);
}

/// Points [p0, p1) of chunk k (its slots zeroed before its first points).
template <int DC, int DP, typename HOf, typename BOf>
void SchurSystem::scatter_chunk_sized(std::size_t k, std::size_t p0, std::size_t p1,
                                      double* gradient, const HOf& h_of, const BOf& b_of,
                                      bool use_direct) {
  if constexpr (DC == 9 && DP == 3) {
    if (use_direct && chunk_standard_[k]) {
      scatter_standard_chunk_9_3(p0, p1, pt_contrib_begin_.data(), direct_edge_.data(),
                                 edge_w_offset_.data(), edge_slot_.data(), pt_v_offset_.data(),
                                 pt_offset_.data(), h_of(pt_contrib_begin_[p0]), v_.data(),
                                 gradient, w_.data(), slots_.data());
      return;
    }
  }
  for (std::size_t p = p0; p < p1; ++p) {
    const int dp = DP > 0 ? DP : pt_dim_[p];
    double* V = v_.data() + pt_v_offset_[p];
    std::fill_n(V, at(dp) * at(dp), 0.0);
    double* g = gradient + pt_offset_[p];
    for (std::size_t e = pt_edge_begin_[p]; e < pt_edge_begin_[p + 1]; ++e) {
      if (use_direct && edge_assigned_[e]) continue;  // its one direct block writes W
      const int dc = DC > 0 ? DC : cam_dim_[at(edge_cam_[e])];
      std::fill_n(w_.data() + edge_w_offset_[e], at(dc) * at(dp), 0.0);
    }
    for (std::size_t q = pt_contrib_begin_[p]; q < pt_contrib_begin_[p + 1]; ++q) {
      const auto [block, local] = pt_contribs_[q];
      if (use_direct && direct_[q]) {
        const std::size_t e = direct_edge_[q];
        const bool has_camera = e != kNoEdge;
        const int dc = has_camera ? cam_dim_[at(edge_cam_[e])] : 0;
        const int n = direct_rows_[q];
        const int D = block_dim(block);
        const double* J = h_of(q);
        const int cam_local = has_camera ? direct_cam_local_[q] : -1;
        double* W = has_camera ? w_.data() + edge_w_offset_[e] : nullptr;
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
      add_packed_block<DP, DP>(h_of(q), at(block_dim(block)), at(local), at(local), dp, dp, V,
                               at(dp));
      const double* b = b_of(q) + local;
      for (int r = 0; r < dp; ++r) g[r] += b[r];
    }
    for (std::size_t e = pt_edge_begin_[p]; e < pt_edge_begin_[p + 1]; ++e) {
      const int dc = cam_dim_[at(edge_cam_[e])];
      double* W = w_.data() + edge_w_offset_[e];
      for (std::size_t q = edge_contrib_begin_[e]; q < edge_contrib_begin_[e + 1]; ++q) {
        const Contribution& src = edge_contribs_[q];
        if (use_direct && direct_[edge_contrib_source_[q]]) continue;
        const double* H = h_of(edge_contrib_source_[q]);
        const auto D = at(block_dim(src.block));
        add_packed_block<DC, DP>(H, D, at(src.row_local), at(src.col_local), dc, dp, W, at(dc));
        if (!fused_) continue;
        double* slot = slots_.data() + edge_slot_[e];
        add_packed_block<DC, DC>(H, D, at(src.row_local), at(src.row_local), dc, dc, slot, at(dc));
        const double* b = b_of(edge_contrib_source_[q]) + src.row_local;
        double* slot_g = slot + at(dc) * at(dc);
        for (int r = 0; r < dc; ++r) slot_g[r] += b[r];
      }
    }
  }
}

template <typename HOf, typename BOf>
void SchurSystem::scatter_chunk(std::size_t k, std::size_t p0, std::size_t p1, double* gradient,
                                const HOf& h_of, const BOf& b_of, bool use_direct) {
  switch (kernel_) {
    case 1:
      scatter_chunk_sized<9, 3>(k, p0, p1, gradient, h_of, b_of, use_direct);
      break;
    case 2:
      scatter_chunk_sized<6, 3>(k, p0, p1, gradient, h_of, b_of, use_direct);
      break;
    default:
      scatter_chunk_sized<0, 0>(k, p0, p1, gradient, h_of, b_of, use_direct);
      break;
  }
}

/// The kept variables: A's blocks (pairs, from `blocks`), their gradients and, fused, the sums
/// of their slots in chunk order.
void SchurSystem::gather_cameras(const BlockLinearizations& blocks, double* gradient) {
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, cam_dim_.size(), 4),
      [&](const tbb::blocked_range<std::size_t>& range) {
        for (std::size_t j = range.begin(); j != range.end(); ++j) {
          const int dj = cam_dim_[j];
          for (std::size_t k = column_pair_begin_[j]; k < column_pair_begin_[j + 1]; ++k) {
            const Pair& pair = pairs_[k];
            const int di = cam_dim_[at(pair.row_cam)];
            double* out = a_.data() + pair.h_offset;
            std::fill_n(out, at(di) * at(dj), 0.0);
            for (std::size_t q = pair.contrib_begin; q < pair.contrib_end; ++q) {
              const Contribution& src = pair_contribs_[q];
              const auto bi = static_cast<std::size_t>(src.block);
              add_packed_block(blocks.h.data() + blocks.h_offset[bi], at(blocks.dim[bi]),
                               at(src.row_local), at(src.col_local), di, dj, out, at(di));
            }
          }
          double* g = gradient + cam_offset_[j];
          for (std::size_t s = cam_grad_begin_[j]; s < cam_grad_begin_[j + 1]; ++s) {
            const auto [block, local] = cam_grad_[s];
            const double* b =
                blocks.b.data() + blocks.b_offset[static_cast<std::size_t>(block)] + local;
            for (int r = 0; r < dj; ++r) g[r] += b[r];
          }
          if (!fused_) continue;
          double* A = a_.data() + pairs_[column_pair_begin_[j]].h_offset;  // the diagonal block
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

void SchurSystem::assemble(const BlockLinearizations& blocks, Eigen::VectorXd* gradient) {
  gradient->setZero(n_);
  double* g = gradient->data();
  const auto h_of = [&](std::size_t q) {
    return blocks.h.data() + blocks.h_offset[static_cast<std::size_t>(pt_contribs_[q].first)];
  };
  const auto b_of = [&](std::size_t q) {
    return blocks.b.data() + blocks.b_offset[static_cast<std::size_t>(pt_contribs_[q].first)];
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

bool SchurSystem::linearize(const BlockEvaluator& evaluator, int which, Eigen::VectorXd* gradient,
                            double* cost, double* linearize_s, double* assembly_s,
                            std::string* error) {
  if (!fused_) {
    return LinearSystem::linearize(evaluator, which, gradient, cost, linearize_s, assembly_s,
                                   error);
  }
  Stopwatch wall;
  gradient->setZero(n_);
  double* g = gradient->data();
  const std::size_t num_blocks = storage_.dim.size();
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
            for (std::size_t q = pt_contrib_begin_[s0]; q < pt_contrib_begin_[s1]; ++q) {
              const auto block = static_cast<std::size_t>(pt_contribs_[q].first);
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
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, other_blocks_.size(), 8),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      BlockScratch& local = scratch.local().block;
                      for (std::size_t k = range.begin(); k != range.end(); ++k) {
                        const std::size_t i = other_blocks_[k];
                        if (!evaluator.evaluate_block(
                                i, which, local, storage_.h.data() + storage_.h_offset[i],
                                storage_.b.data() + storage_.b_offset[i], &storage_.cost[i])) {
                          record_bad_block(first_bad, i);
                        }
                      }
                    });
  const double evaluated_s = wall.elapsed_s();
  const std::size_t bad = first_bad.load();
  if (bad < num_blocks) {
    *linearize_s += evaluated_s;
    *error = evaluator.describe_bad_block(bad, which);
    return false;
  }
  wall.restart();
  gather_cameras(storage_, g);
  const double gathered_s = wall.elapsed_s();
  // The chunk pass did both; split its wall time by the CPU time of each part.
  double evaluate_total = 0.0, scatter_total = 0.0;
  for (std::size_t k = 0; k < num_chunks; ++k) {
    evaluate_total += evaluate_cpu[k];
    scatter_total += scatter_cpu[k];
  }
  const double scatter_share =
      evaluate_total + scatter_total > 0.0 ? scatter_total / (evaluate_total + scatter_total) : 0.0;
  *linearize_s += evaluated_s * (1.0 - scatter_share);
  *assembly_s += evaluated_s * scatter_share + gathered_s;
  double total = 0.0;
  for (const double c : chunk_cost_) total += c;
  for (const std::size_t i : other_blocks_) total += storage_.cost[i];
  *cost = total;
  return true;
}

Eigen::VectorXd SchurSystem::diagonal() const {
  Eigen::VectorXd d(n_);
  for (std::size_t j = 0; j < cam_dim_.size(); ++j) {
    const int dj = cam_dim_[j];
    const double* A = a_.data() + pairs_[column_pair_begin_[j]].h_offset;  // diagonal pair first
    for (int r = 0; r < dj; ++r) d[cam_offset_[j] + r] = A[at(r) * at(dj) + at(r)];
  }
  for (std::size_t p = 0; p < pt_dim_.size(); ++p) {
    const int dp = pt_dim_[p];
    const double* V = v_.data() + pt_v_offset_[p];
    for (int r = 0; r < dp; ++r) d[pt_offset_[p] + r] = V[at(r) * at(dp) + at(r)];
  }
  return d;
}

/// L^-1 (3 x 3, column-major, lower; the upper part zero) for V + diag(d) = L L^T, V symmetric
/// 3 x 3 column-major; false if V + diag(d) is not positive definite (or not finite).
inline bool inverse_cholesky_3(const double* V, const double* d, double* L_inverse) {
  const double a = V[0] + d[0];
  if (!(a > 0.0)) return false;
  const double l00 = std::sqrt(a);
  const double l10 = V[1] / l00;
  const double l20 = V[2] / l00;
  const double b = V[4] + d[1] - l10 * l10;
  if (!(b > 0.0)) return false;
  const double l11 = std::sqrt(b);
  const double l21 = (V[5] - l20 * l10) / l11;
  const double c = V[8] + d[2] - l20 * l20 - l21 * l21;
  if (!(c > 0.0)) return false;
  const double l22 = std::sqrt(c);
  const double i00 = 1.0 / l00, i11 = 1.0 / l11, i22 = 1.0 / l22;
  const double i10 = -l10 * i00 * i11;
  const double i21 = -l21 * i11 * i22;
  const double i20 = -(l20 * i00 + l21 * i10) * i22;
  L_inverse[0] = i00;
  L_inverse[1] = i10;
  L_inverse[2] = i20;
  L_inverse[3] = 0.0;
  L_inverse[4] = i11;
  L_inverse[5] = i21;
  L_inverse[6] = 0.0;
  L_inverse[7] = 0.0;
  L_inverse[8] = i22;
  return std::isfinite(i20) && std::isfinite(i21) && std::isfinite(i10);
}

/// Per point: V + damping = L L^T, L^-1 kept, and Y = W L^-T per edge, so that
/// W V^-1 W^T = Y Y^T. False if a V is not positive definite.
template <int DC, int DP>
bool SchurSystem::eliminate_points(const Eigen::VectorXd& damping) {
  std::atomic<bool> failed{false};
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, pt_dim_.size(), 256),
      [&](const tbb::blocked_range<std::size_t>& range) {
        using MatrixP = Eigen::Matrix<double, DP, DP>;
        MatrixP V_damped;
        Eigen::LLT<MatrixP> llt;
        for (std::size_t p = range.begin(); p != range.end(); ++p) {
          const int dp = pt_dim_[p];
          MapMatrix<DP, DP> L_inverse(l_inverse_.data() + pt_v_offset_[p], dp, dp);
          if constexpr (DP == 3) {
            if (!inverse_cholesky_3(v_.data() + pt_v_offset_[p], damping.data() + pt_offset_[p],
                                    L_inverse.data())) {
              failed.store(true, std::memory_order_relaxed);
              continue;
            }
          } else {
            V_damped = ConstMapMatrix<DP, DP>(v_.data() + pt_v_offset_[p], dp, dp);
            V_damped.diagonal() += damping.segment(pt_offset_[p], dp);
            llt.compute(V_damped);
            if (llt.info() != Eigen::Success) {
              failed.store(true, std::memory_order_relaxed);
              continue;
            }
            L_inverse.setIdentity(dp, dp);
            llt.matrixL().solveInPlace(L_inverse);
          }
        }
      });
  return !failed.load();
}

namespace {

/// What one column of S needs from the system (see SchurSystem::form_reduced_system()).
struct GroupInput {
  const std::size_t* points_begin;  // the points the group's cameras see, ascending
  const std::size_t* points_end;
  int first_camera;  // the group: cameras [first_camera, end_camera)
  int end_camera;
  std::size_t num_cameras;
  const int* edge_cam;
  const std::size_t* edge_y_offset;
  const std::size_t* pt_edge_begin;
  const int* cam_dim;
  const int* pt_dim;
  const double* w;          // W per edge (edge_y_offset)
  const double* l_inverse;  // L^-1 per point (pt_v_offset)
  const std::size_t* pt_v_offset;
  double* y;                      // scratch: Y = W L^-T of one point's edges
  const std::size_t* row_offset;  // [(j - first_camera) * num_cameras + i]: block (i, j) in stack
  double* stack;                  // the group's columns of S blocks (column-major per block)
};

/// S (di x dj, column-major) -= Y1 (di x dp) Y2^T (dj x dp).
template <int DC, int DP>
__attribute__((always_inline)) inline void subtract_product(double* __restrict S,
                                                            const double* __restrict Y1,
                                                            const double* __restrict Y2, int di,
                                                            int dj, int dp) {
  const int DI = DC == Eigen::Dynamic ? di : DC;
  const int DJ = DC == Eigen::Dynamic ? dj : DC;
  const int DPP = DP == Eigen::Dynamic ? dp : DP;
  for (int c = 0; c < DJ; ++c) {
    double* out = S + c * DI;
    for (int k = 0; k < DPP; ++k) {
      const double w = Y2[k * DJ + c];
      const double* in = Y1 + k * DI;
      for (int r = 0; r < DI; ++r) out[r] -= in[r] * w;
    }
  }
}

/// For every point a camera of the group sees, in point order, and each such camera j:
/// S_ij -= Y_ip Y_jp^T for every camera i >= j that sees the point too (the point's edges from
/// j's own one on, by camera). A point's edges are read once per group, not once per camera.
template <int DC, int DP>
__attribute__((always_inline)) inline void reduce_group_body(const GroupInput& in) {
  for (const std::size_t* it = in.points_begin; it != in.points_end; ++it) {
    const std::size_t p = *it;
    const int dp = in.pt_dim[p];
    const std::size_t end = in.pt_edge_begin[p + 1];
    std::size_t first = in.pt_edge_begin[p];
    while (first < end && in.edge_cam[first] < in.first_camera) ++first;
    // Y = W L^-T of the edges from the group's first one on (W V^-1 W^T = Y Y^T).
    const ConstMapMatrix<DP, DP> L_inverse(in.l_inverse + in.pt_v_offset[p], dp, dp);
    std::size_t y_offset = 0;
    for (std::size_t f = first; f < end; ++f) {
      const int dc = in.cam_dim[in.edge_cam[f]];
      MapMatrix<DC, DP>(in.y + y_offset, dc, dp).noalias() =
          ConstMapMatrix<DC, DP>(in.w + in.edge_y_offset[f], dc, dp)
              .lazyProduct(L_inverse.transpose());
      y_offset += static_cast<std::size_t>(dc) * static_cast<std::size_t>(dp);
    }
    std::size_t ye = 0;  // offset of edge e's Y
    for (std::size_t e = first; e < end; ++e) {
      const int j = in.edge_cam[e];
      if (j >= in.end_camera) break;
      const int dj = in.cam_dim[j];
      const double* Yj = in.y + ye;
      const std::size_t* offsets =
          in.row_offset + static_cast<std::size_t>(j - in.first_camera) * in.num_cameras;
      std::size_t yf = ye;
      for (std::size_t f = e; f < end; ++f) {
        const auto i = static_cast<std::size_t>(in.edge_cam[f]);
        subtract_product<DC, DP>(in.stack + offsets[i], in.y + yf, Yj, in.cam_dim[i], dj, dp);
        yf += static_cast<std::size_t>(in.cam_dim[i]) * static_cast<std::size_t>(dp);
      }
      ye += static_cast<std::size_t>(dj) * static_cast<std::size_t>(dp);
    }
  }
}

CARAT_MULTIVERSION void reduce_group_9_3(const GroupInput& in) { reduce_group_body<9, 3>(in); }
CARAT_MULTIVERSION void reduce_group_6_3(const GroupInput& in) { reduce_group_body<6, 3>(in); }
CARAT_MULTIVERSION void reduce_group_any(const GroupInput& in) {
  reduce_group_body<Eigen::Dynamic, Eigen::Dynamic>(in);
}

}  // namespace

/// S = A + diag(damping) - sum over shared points of Y_i Y_j^T, into the CSC values; a column of
/// camera blocks per task, each block's sum in point order.
template <int DC, int DP>
void SchurSystem::form_reduced_system(const Eigen::VectorXd& damping) {
  struct GroupScratch {
    std::vector<double> stack;
    std::vector<std::size_t> row_offset;
    std::vector<double> y;
  };
  const std::size_t nc = cam_dim_.size();
  const std::size_t num_groups = group_points_begin_.size() - 1;
  tbb::enumerable_thread_specific<GroupScratch> scratch;
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, num_groups, 1),
      [&](const tbb::blocked_range<std::size_t>& range) {
        GroupScratch& local = scratch.local();
        local.stack.resize(max_group_values_);
        local.row_offset.resize(kGroupCameras * nc);
        local.y.resize(max_point_y_);
        for (std::size_t group = range.begin(); group != range.end(); ++group) {
          const auto [j0, j1] = group_range(group);
          // The group's blocks, stacked, start as A (+ damping on the diagonal blocks).
          std::size_t offset = 0;
          for (std::size_t j = j0; j < j1; ++j) {
            const int dj = cam_dim_[j];
            std::size_t* rows = local.row_offset.data() + (j - j0) * nc;
            for (std::size_t k = column_pair_begin_[j]; k < column_pair_begin_[j + 1]; ++k) {
              const Pair& pair = pairs_[k];
              const std::size_t size = at(cam_dim_[at(pair.row_cam)]) * at(dj);
              rows[at(pair.row_cam)] = offset;
              std::copy_n(a_.data() + pair.h_offset, size, local.stack.data() + offset);
              offset += size;
            }
            double* diagonal = local.stack.data() + rows[j];
            for (int r = 0; r < dj; ++r)
              diagonal[at(r) * at(dj) + at(r)] += damping[cam_offset_[j] + r];
          }
          const GroupInput in{group_points_.data() + group_points_begin_[group],
                              group_points_.data() + group_points_begin_[group + 1],
                              static_cast<int>(j0),
                              static_cast<int>(j1),
                              nc,
                              edge_cam_.data(),
                              edge_w_offset_.data(),
                              pt_edge_begin_.data(),
                              cam_dim_.data(),
                              pt_dim_.data(),
                              w_.data(),
                              l_inverse_.data(),
                              pt_v_offset_.data(),
                              local.y.data(),
                              local.row_offset.data(),
                              local.stack.data()};
          if constexpr (DC == 9 && DP == 3) {
            reduce_group_9_3(in);
          } else if constexpr (DC == 6 && DP == 3) {
            reduce_group_6_3(in);
          } else {
            reduce_group_any(in);
          }
          for (std::size_t j = j0; j < j1; ++j) {
            const int dj = cam_dim_[j];
            const std::size_t* rows = local.row_offset.data() + (j - j0) * nc;
            for (std::size_t k = column_pair_begin_[j]; k < column_pair_begin_[j + 1]; ++k) {
              const Pair& pair = pairs_[k];
              const int di = cam_dim_[at(pair.row_cam)];
              const double* S = local.stack.data() + rows[at(pair.row_cam)];
              const bool diagonal = at(pair.row_cam) == j;
              for (int c = 0; c < dj; ++c) {
                double* column = values_.data() + colptr_[at(cam_offset_[j] + c)];
                const double* src = S + at(c) * at(di);
                if (diagonal) {
                  for (int r = c; r < dj; ++r) column[r - c] = src[r];
                } else {
                  double* dst = column + (dj - c) + pair.row_in_column;
                  for (int r = 0; r < di; ++r) dst[r] = src[r];
                }
              }
            }
          }
        }
      });
}

bool SchurSystem::factorize(const Eigen::VectorXd& damping) {
  const Stopwatch t0;
  bool ok = false;
  switch (kernel_) {
    case 1:
      ok = eliminate_points<9, 3>(damping);
      if (ok) form_reduced_system<9, 3>(damping);
      break;
    case 2:
      ok = eliminate_points<6, 3>(damping);
      if (ok) form_reduced_system<6, 3>(damping);
      break;
    default:
      ok = eliminate_points<Eigen::Dynamic, Eigen::Dynamic>(damping);
      if (ok) form_reduced_system<Eigen::Dynamic, Eigen::Dynamic>(damping);
      break;
  }
  elimination_s_ += t0.elapsed_s();
  if (!ok) return false;
  if (ns_ == 0) return true;
  return cholmod_->factorize();
}

/// u = V^-1 rhs_point = L^-T L^-1 rhs_point per point (kept in z_), then reduced =
/// rhs_cameras - sum over each camera's edges of W_e u_point.
template <int DC, int DP>
void SchurSystem::reduce_rhs(const Eigen::VectorXd& rhs, double* reduced) {
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, pt_dim_.size(), 512),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t p = range.begin(); p != range.end(); ++p) {
                        const int dp = pt_dim_[p];
                        const ConstMapMatrix<DP, DP> L_inverse(l_inverse_.data() + pt_v_offset_[p],
                                                               dp, dp);
                        MapVector<DP>(z_.data() + (pt_offset_[p] - ns_), dp).noalias() =
                            L_inverse.transpose().lazyProduct(
                                L_inverse.lazyProduct(rhs.segment(pt_offset_[p], dp)));
                      }
                    });
  // Per group of cameras (as in form_reduced_system()): each point's edges read in sequence,
  // each camera's sum in point order.
  const std::size_t num_groups = group_points_begin_.size() - 1;
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, num_groups, 1),
      [&](const tbb::blocked_range<std::size_t>& range) {
        for (std::size_t group = range.begin(); group != range.end(); ++group) {
          const auto [j0, j1] = group_range(group);
          for (std::size_t c = j0; c < j1; ++c) {
            const int dc = cam_dim_[c];
            MapVector<DC>(reduced + cam_offset_[c], dc) = rhs.segment(cam_offset_[c], dc);
          }
          for (std::size_t k = group_points_begin_[group]; k < group_points_begin_[group + 1];
               ++k) {
            const std::size_t p = group_points_[k];
            const int dp = pt_dim_[p];
            const ConstMapVector<DP> z(z_.data() + (pt_offset_[p] - ns_), dp);
            for (std::size_t e = pt_edge_begin_[p]; e < pt_edge_begin_[p + 1]; ++e) {
              const auto c = at(edge_cam_[e]);
              if (c < j0) continue;
              if (c >= j1) break;
              const int dc = cam_dim_[c];
              MapVector<DC>(reduced + cam_offset_[c], dc).noalias() -=
                  ConstMapMatrix<DC, DP>(w_.data() + edge_w_offset_[e], dc, dp).lazyProduct(z);
            }
          }
        }
      });
}

/// x_point = V^-1 (rhs_point - sum over its edges of W_e^T x_camera); x_cameras copied.
template <int DC, int DP>
void SchurSystem::back_substitute(const Eigen::VectorXd& rhs, const double* x_cameras,
                                  double* x) const {
  std::copy_n(x_cameras, ns_, x);
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, pt_dim_.size(), 256),
      [&](const tbb::blocked_range<std::size_t>& range) {
        Eigen::Matrix<double, DP, 1> t;
        for (std::size_t p = range.begin(); p != range.end(); ++p) {
          const int dp = pt_dim_[p];
          t = rhs.segment(pt_offset_[p], dp);
          for (std::size_t e = pt_edge_begin_[p]; e < pt_edge_begin_[p + 1]; ++e) {
            const auto c = at(edge_cam_[e]);
            const int dc = cam_dim_[c];
            t.noalias() -= ConstMapMatrix<DC, DP>(w_.data() + edge_w_offset_[e], dc, dp)
                               .transpose()
                               .lazyProduct(ConstMapVector<DC>(x_cameras + cam_offset_[c], dc));
          }
          const ConstMapMatrix<DP, DP> L_inverse(l_inverse_.data() + pt_v_offset_[p], dp, dp);
          MapVector<DP>(x + pt_offset_[p], dp).noalias() =
              L_inverse.transpose().lazyProduct(L_inverse.lazyProduct(t));
        }
      });
}

void SchurSystem::solve(const Eigen::VectorXd& rhs, Eigen::VectorXd* x) {
  Stopwatch t0;
  Eigen::VectorXd reduced(ns_);
  switch (kernel_) {
    case 1:
      reduce_rhs<9, 3>(rhs, reduced.data());
      break;
    case 2:
      reduce_rhs<6, 3>(rhs, reduced.data());
      break;
    default:
      reduce_rhs<Eigen::Dynamic, Eigen::Dynamic>(rhs, reduced.data());
      break;
  }
  elimination_s_ += t0.elapsed_s();
  const double* x_cameras = reduced.data();
  if (ns_ > 0) {
    x_cameras_.resize(at(ns_));
    cholmod_->solve(reduced.data(), x_cameras_.data(), "Schur complement");
    x_cameras = x_cameras_.data();
  }
  t0.restart();
  x->resize(n_);
  switch (kernel_) {
    case 1:
      back_substitute<9, 3>(rhs, x_cameras, x->data());
      break;
    case 2:
      back_substitute<6, 3>(rhs, x_cameras, x->data());
      break;
    default:
      back_substitute<Eigen::Dynamic, Eigen::Dynamic>(rhs, x_cameras, x->data());
      break;
  }
  elimination_s_ += t0.elapsed_s();
}

void SchurSystem::multiply(const Eigen::VectorXd& x, Eigen::VectorXd* y) const {
  y->setZero(n_);
  for (std::size_t j = 0; j < cam_dim_.size(); ++j) {
    const int dj = cam_dim_[j];
    for (std::size_t k = column_pair_begin_[j]; k < column_pair_begin_[j + 1]; ++k) {
      const Pair& pair = pairs_[k];
      const auto i = at(pair.row_cam);
      const int di = cam_dim_[i];
      const ConstMapMatrix<Eigen::Dynamic, Eigen::Dynamic> A(a_.data() + pair.h_offset, di, dj);
      y->segment(cam_offset_[i], di).noalias() += A * x.segment(cam_offset_[j], dj);
      if (i != j) {
        y->segment(cam_offset_[j], dj).noalias() += A.transpose() * x.segment(cam_offset_[i], di);
      }
    }
  }
  for (std::size_t p = 0; p < pt_dim_.size(); ++p) {
    const int dp = pt_dim_[p];
    const ConstMapMatrix<Eigen::Dynamic, Eigen::Dynamic> V(v_.data() + pt_v_offset_[p], dp, dp);
    y->segment(pt_offset_[p], dp).noalias() += V * x.segment(pt_offset_[p], dp);
    for (std::size_t e = pt_edge_begin_[p]; e < pt_edge_begin_[p + 1]; ++e) {
      const auto c = at(edge_cam_[e]);
      const int dc = cam_dim_[c];
      const ConstMapMatrix<Eigen::Dynamic, Eigen::Dynamic> W(w_.data() + edge_w_offset_[e], dc, dp);
      y->segment(cam_offset_[c], dc).noalias() += W * x.segment(pt_offset_[p], dp);
      y->segment(pt_offset_[p], dp).noalias() += W.transpose() * x.segment(cam_offset_[c], dc);
    }
  }
}

int SchurSystem::eliminated_at(int offset) const {
  const auto it = std::lower_bound(pt_offset_.begin(), pt_offset_.end(), offset);
  if (it == pt_offset_.end() || *it != offset) return -1;
  return static_cast<int>(it - pt_offset_.begin());
}

double SchurSystem::take_elimination_seconds() {
  const double s = elimination_s_;
  elimination_s_ = 0.0;
  return s;
}

}  // namespace carat::internal
