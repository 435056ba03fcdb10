#include "schur_structure.hpp"

#include <tbb/task_arena.h>

#include <algorithm>
#include <cstdint>
#include <string>
#include <tuple>

#include "carat/base/error.hpp"

namespace carat::internal {
namespace {

std::size_t at(int k) { return static_cast<std::size_t>(k); }

/// Throws the error of block `block` connecting eliminable variables `first` and `second`.
[[noreturn]] void refuse_shared_block(std::size_t block, int first, int second) {
  throw Error("Schur complement: residual block " + std::to_string(block) +
              " connects two eliminable variables (" + std::to_string(first) + " and " +
              std::to_string(second) + "); the eliminated variables must not share a block");
}

/// Groups of consecutive cameras for forming S: at most kMaxGroupCameras each, and at least two
/// groups a thread of the calling arena where the cameras allow groups of 8; the points each
/// group sees (ascending) and the values of its stacked columns of S blocks.
void build_groups(SchurStructure& s) {
  const std::size_t nc = s.num_cameras();
  const std::size_t np = s.num_points();
  const auto threads =
      static_cast<std::size_t>(std::max(1, tbb::this_task_arena::max_concurrency()));
  s.group_cameras = threads == 1 ? SchurStructure::kMaxGroupCameras
                                 : std::clamp<std::size_t>((nc + 2 * threads - 1) / (2 * threads),
                                                           8, SchurStructure::kMaxGroupCameras);
  const std::size_t num_groups = (nc + s.group_cameras - 1) / s.group_cameras;
  s.group_points_begin.assign(num_groups + 1, 0);
  std::vector<std::size_t> seen(np, num_groups);  // group that last listed point p
  for (std::size_t group = 0; group < num_groups; ++group) {
    const std::size_t first = s.group_points.size();
    std::size_t values = 0;
    for (std::size_t j = group * s.group_cameras; j < std::min(nc, (group + 1) * s.group_cameras);
         ++j) {
      for (std::size_t k = s.cam_edge_begin[j]; k < s.cam_edge_begin[j + 1]; ++k) {
        const auto p = at(s.edge_pt[s.cam_edges[k]]);
        if (seen[p] != group) {
          seen[p] = group;
          s.group_points.push_back(p);
        }
      }
      for (std::size_t k = s.column_pair_begin[j]; k < s.column_pair_begin[j + 1]; ++k) {
        values += at(s.cam_dim[at(s.pairs[k].row_cam)]) * at(s.cam_dim[j]);
      }
    }
    std::sort(s.group_points.begin() + static_cast<std::ptrdiff_t>(first), s.group_points.end());
    for (std::size_t k = first; k < s.group_points.size(); ++k) {
      const std::size_t p = s.group_points[k];
      std::size_t size = 0;
      for (std::size_t e = s.pt_edge_begin[p]; e < s.pt_edge_begin[p + 1]; ++e) {
        size += at(s.cam_dim[at(s.edge_cam[e])]) * at(s.pt_dim[p]);
      }
      s.max_point_y = std::max(s.max_point_y, size);
    }
    s.group_points_begin[group + 1] = s.group_points.size();
    s.max_group_values = std::max(s.max_group_values, values);
  }
}

/// S's lower-triangular pattern in camera order: per scalar column of camera j, the diagonal
/// block's rows from the diagonal down, then the blocks of the cameras below it.
void build_pattern(SchurStructure& s) {
  const std::size_t nc = s.num_cameras();
  s.colptr.assign(at(s.ns) + 1, 0);
  for (std::size_t j = 0; j < nc; ++j) {
    const int dj = s.cam_dim[j];
    std::int64_t below = 0;
    for (std::size_t k = s.column_pair_begin[j]; k < s.column_pair_begin[j + 1]; ++k) {
      if (at(s.pairs[k].row_cam) == j) continue;
      s.pairs[k].row_in_column = below;
      below += s.cam_dim[at(s.pairs[k].row_cam)];
    }
    for (int c = 0; c < dj; ++c) {
      const std::size_t col = at(s.cam_offset[j] + c);
      s.colptr[col + 1] = s.colptr[col] + (dj - c) + below;
    }
  }
  s.rows.assign(static_cast<std::size_t>(s.colptr.back()), 0);
  for (std::size_t j = 0; j < nc; ++j) {
    const int dj = s.cam_dim[j];
    for (int c = 0; c < dj; ++c) {
      auto pos = static_cast<std::size_t>(s.colptr[at(s.cam_offset[j] + c)]);
      for (int r = c; r < dj; ++r) s.rows[pos++] = s.cam_offset[j] + r;
      for (std::size_t k = s.column_pair_begin[j]; k < s.column_pair_begin[j + 1]; ++k) {
        const auto i = at(s.pairs[k].row_cam);
        if (i == j) continue;
        for (int r = 0; r < s.cam_dim[i]; ++r) s.rows[pos++] = s.cam_offset[i] + r;
      }
    }
  }
}

}  // namespace

std::vector<char> free_marked(const Problem& problem, const std::vector<char>& eliminate) {
  std::vector<char> marked(eliminate.size(), 0);
  for (std::size_t v = 0; v < eliminate.size(); ++v) {
    marked[v] = eliminate[v] && !problem.is_constant(VariableId{static_cast<int>(v)});
  }
  return marked;
}

void check_eliminable_group(const Problem& problem, const std::vector<char>& eliminate) {
  const std::vector<char> eliminated = free_marked(problem, eliminate);
  const auto blocks = problem.blocks();
  for (std::size_t bi = 0; bi < blocks.size(); ++bi) {
    int first = -1;
    for (VariableId v : blocks[bi].variables) {
      if (!eliminated[at(v.index)]) continue;
      if (first >= 0) refuse_shared_block(bi, first, v.index);
      first = v.index;
    }
  }
}

SchurStructure::SchurStructure(const Problem& problem, const std::vector<char>& eliminate) {
  const int num_vars = problem.num_variables();
  var_offset.assign(at(num_vars), -1);
  // Per variable, in one record (a block's variables are read at random): its camera or point
  // index (-1: neither) and its tangent size.
  struct Role {
    int cam = -1;
    int pt = -1;
    int dim = 0;
  };
  std::vector<Role> role(at(num_vars));
  for (int v = 0; v < num_vars; ++v) {
    const VariableId id{v};
    const int d = problem.manifold(id).tangent_size();
    role[at(v)].dim = d;
    if (problem.is_constant(id)) continue;
    if (eliminate[at(v)]) {
      role[at(v)].pt = static_cast<int>(pt_dim.size());
      pt_dim.push_back(d);
    } else {
      role[at(v)].cam = static_cast<int>(cam_dim.size());
      cam_offset.push_back(ns);
      cam_dim.push_back(d);
      var_offset[at(v)] = ns;
      ns += d;
    }
  }
  n = ns;
  for (int v = 0; v < num_vars; ++v) {
    if (role[at(v)].pt < 0) continue;
    const int d = role[at(v)].dim;
    var_offset[at(v)] = n;
    pt_offset.push_back(n);
    pt_v_offset.push_back(v_size);
    n += d;
    v_size += at(d) * at(d);
  }
  const std::size_t nc = cam_dim.size();
  const std::size_t np = pt_dim.size();

  // Fixed-size kernels when every camera and every point have the same common dimension.
  const auto all_equal = [](const std::vector<int>& dims, int d) {
    return std::all_of(dims.begin(), dims.end(), [d](int x) { return x == d; });
  };
  if (all_equal(pt_dim, 3) && all_equal(cam_dim, 9)) kernel = SchurKernel::kCamera9Point3;
  if (all_equal(pt_dim, 3) && all_equal(cam_dim, 6)) kernel = SchurKernel::kCamera6Point3;

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
  std::vector<std::pair<int, int>> cams;  // (camera, local) of one block
  // Fused: the kept-variable part of a block with a point is one diagonal block (of its one
  // camera), summed per chunk of points (slots below) rather than gathered per camera; such
  // blocks then list no camera gradient nor camera pair. The first pass assumes it and leaves
  // those out; a block with a point and two cameras ends the assumption and a second pass lists
  // every block's.
  const auto collect = [&](bool assume_fused) {
    raw_pairs.clear();
    raw_edges.clear();
    raw_pt.clear();
    raw_cam.clear();
    block_dims.clear();
    raw_cam.reserve(blocks.size());
    raw_pairs.reserve(assume_fused ? 0 : blocks.size());
    raw_edges.reserve(blocks.size());
    raw_pt.reserve(blocks.size());
    block_dims.reserve(blocks.size());
    for (std::size_t bi = 0; bi < blocks.size(); ++bi) {
      cams.clear();
      int point = -1;
      int point_var = -1;
      int point_local = 0;
      int local = 0;
      for (VariableId v : blocks[bi].variables) {
        const Role& r = role[at(v.index)];
        if (r.cam >= 0) cams.emplace_back(r.cam, local);
        if (r.pt >= 0) {
          if (point >= 0) refuse_shared_block(bi, point_var, v.index);
          point = r.pt;
          point_var = v.index;
          point_local = local;
        }
        local += r.dim;
      }
      block_dims.push_back(local);
      const auto block = static_cast<std::int32_t>(bi);
      if (point >= 0) {
        if (cams.size() > 1 && assume_fused) return false;
        raw_pt.emplace_back(point, block, static_cast<std::int16_t>(point_local));
        for (const auto& [ca, la] : cams) {
          raw_edges.push_back({point, ca, block, static_cast<std::int16_t>(la),
                               static_cast<std::int16_t>(point_local)});
        }
        if (assume_fused) continue;
      }
      for (const auto& [ca, la] : cams) {
        raw_cam.emplace_back(ca, block, static_cast<std::int16_t>(la));
        for (const auto& [cb, lb] : cams) {
          if (ca < cb) continue;
          raw_pairs.push_back(
              {cb, ca, block, static_cast<std::int16_t>(la), static_cast<std::int16_t>(lb)});
        }
      }
    }
    return true;
  };
  fused = collect(true);
  if (!fused) collect(false);

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
  pt_edge_begin.assign(np + 1, 0);
  edge_cam.reserve(raw_edges.size());
  edge_pt.reserve(raw_edges.size());
  edge_w_offset.reserve(raw_edges.size());
  edge_contrib_begin.reserve(raw_edges.size() + 1);
  edge_contribs.reserve(raw_edges.size());
  for (std::size_t k = 0; k < raw_edges.size();) {
    const RawEdge& first = raw_edges[k];
    edge_cam.push_back(first.cam);
    edge_pt.push_back(first.pt);
    edge_w_offset.push_back(w_size);
    w_size += at(cam_dim[at(first.cam)]) * at(pt_dim[at(first.pt)]);
    edge_contrib_begin.push_back(edge_contribs.size());
    for (; k < raw_edges.size() && raw_edges[k].pt == first.pt && raw_edges[k].cam == first.cam;
         ++k) {
      edge_contribs.push_back({raw_edges[k].block, raw_edges[k].cam_local, raw_edges[k].pt_local});
    }
    pt_edge_begin[at(first.pt) + 1] = edge_cam.size();
  }
  edge_contrib_begin.push_back(edge_contribs.size());
  for (std::size_t p = 1; p <= np; ++p)
    pt_edge_begin[p] = std::max(pt_edge_begin[p], pt_edge_begin[p - 1]);
  raw_edges = {};
  const std::size_t num_edges = edge_cam.size();

  // Each camera's edges in point order.
  cam_edge_begin.assign(nc + 1, 0);
  for (std::size_t e = 0; e < num_edges; ++e) ++cam_edge_begin[at(edge_cam[e]) + 1];
  for (std::size_t c = 0; c < nc; ++c) cam_edge_begin[c + 1] += cam_edge_begin[c];
  cam_edges.resize(num_edges);
  {
    std::vector<std::size_t> fill(cam_edge_begin.begin(), cam_edge_begin.end() - 1);
    for (std::size_t e = 0; e < num_edges; ++e) cam_edges[fill[at(edge_cam[e])]++] = e;
  }

  // Points' V and gradient contributions; cameras' gradient contributions.
  // By point, blocks ascending: raw_pt is in block order, so a stable counting sort by point.
  pt_contrib_begin.assign(np + 1, 0);
  for (const auto& [p, block, local] : raw_pt) ++pt_contrib_begin[at(p) + 1];
  for (std::size_t p = 0; p < np; ++p) pt_contrib_begin[p + 1] += pt_contrib_begin[p];
  pt_contribs.resize(raw_pt.size());
  {
    std::vector<std::size_t> fill(pt_contrib_begin.begin(), pt_contrib_begin.end() - 1);
    for (const auto& [p, block, local] : raw_pt) pt_contribs[fill[at(p)]++] = {block, local};
  }
  // Where each block with a point sits in pt_contribs (its source index).
  std::vector<std::uint32_t> block_source(blocks.size(), 0);
  for (std::size_t k = 0; k < pt_contribs.size(); ++k) {
    block_source[static_cast<std::size_t>(pt_contribs[k].first)] = static_cast<std::uint32_t>(k);
  }
  edge_contrib_source.resize(edge_contribs.size());
  for (std::size_t q = 0; q < edge_contribs.size(); ++q) {
    edge_contrib_source[q] = block_source[static_cast<std::size_t>(edge_contribs[q].block)];
  }
  // By camera, blocks ascending (raw_cam is in block order, one entry per block and camera).
  cam_grad_begin.assign(nc + 1, 0);
  for (const auto& [c, block, local] : raw_cam) ++cam_grad_begin[at(c) + 1];
  for (std::size_t c = 0; c < nc; ++c) cam_grad_begin[c + 1] += cam_grad_begin[c];
  cam_grad.resize(raw_cam.size());
  {
    std::vector<std::size_t> fill(cam_grad_begin.begin(), cam_grad_begin.end() - 1);
    for (const auto& [c, block, local] : raw_cam) cam_grad[fill[at(c)]++] = {block, local};
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
    std::vector<int> row_cams;
    for (std::size_t j = 0; j < nc; ++j) {
      row_cams.clear();
      const auto mark = [&](int i) {
        if (marked[at(i)] != j) {
          marked[at(i)] = j;
          row_cams.push_back(i);
        }
      };
      mark(static_cast<int>(j));
      for (const int i : block_rows[j]) mark(i);
      for (std::size_t k = cam_edge_begin[j]; k < cam_edge_begin[j + 1]; ++k) {
        const std::size_t e = cam_edges[k];
        for (std::size_t f = e; f < pt_edge_begin[at(edge_pt[e]) + 1]; ++f) mark(edge_cam[f]);
      }
      std::sort(row_cams.begin(), row_cams.end());
      for (const int i : row_cams) keys.push_back(key(static_cast<int>(j), i));
    }
  }
  const auto pair_index = [&](int col, int row) {
    return static_cast<std::size_t>(std::lower_bound(keys.begin(), keys.end(), key(col, row)) -
                                    keys.begin());
  };
  pairs.resize(keys.size());
  column_pair_begin.assign(nc + 1, 0);
  for (std::size_t k = 0; k < keys.size(); ++k) {
    const auto col = static_cast<int>(keys[k] >> 32);
    const auto row = static_cast<int>(keys[k] & 0xffffffffu);
    pairs[k].row_cam = row;
    pairs[k].h_offset = a_size;
    a_size += at(cam_dim[at(row)]) * at(cam_dim[at(col)]);
    ++column_pair_begin[at(col) + 1];
  }
  for (std::size_t c = 0; c < nc; ++c) column_pair_begin[c + 1] += column_pair_begin[c];

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
    pair_contribs.resize(raw_pairs.size());
    for (std::size_t k = 0; k < keys.size(); ++k) {
      pairs[k].contrib_begin = count[k];
      pairs[k].contrib_end = count[k + 1];
    }
    for (std::size_t k = 0; k < raw_pairs.size(); ++k) {
      pair_contribs[count[pair_of[k]]++] = {raw_pairs[k].block, raw_pairs[k].row_local,
                                            raw_pairs[k].col_local};
    }
  }
  raw_pairs = {};
  build_groups(*this);
  build_pattern(*this);
}

}  // namespace carat::internal
