#include "carat/registration/kdtree.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <numeric>

#include "carat/base/multiversion.hpp"

namespace carat {
namespace {

/// Most points a leaf holds: large leaves, scanned a vector at a time, keep the descents short
/// (on 0.25 m scans of 11,000 points, leaves of 56 answer in two thirds of the time of 20).
constexpr std::uint32_t kLeafSize = 56;
/// Node::dim of a leaf.
constexpr std::uint32_t kLeaf = 3;
/// Lanes of one group of leaf points: a leaf's points are stored as whole groups of this many
/// x, y and z coordinates, padded with points at infinity (never closer than any bound).
constexpr std::uint32_t kLanes = 8;
/// Groups of lanes a leaf spans at most.
constexpr std::uint32_t kLeafGroups = (kLeafSize + kLanes - 1) / kLanes;
/// Deepest path a search can take (a median split halves a cell; 2^32 points need 32 levels).
constexpr int kMaxDepth = 64;

/// Eight floats, one vector register (or two, or four narrower ones, depending on the clone).
typedef float Lanes __attribute__((vector_size(kLanes * sizeof(float))));
/// Eight lane indices.
typedef std::int32_t LaneIndices __attribute__((vector_size(kLanes * sizeof(std::int32_t))));

/// A tree node. Inner: the points with coordinate `dim` below `split` are in the left child
/// (the next node), those above in the right child (node `right_or_begin`), those equal in
/// either.
/// Leaf: points [begin, end) of the leaf-ordered arrays; `begin` is a multiple of kLanes.
struct Node {
  float split = 0.0f;
  std::uint32_t dim = kLeaf;
  std::uint32_t right_or_begin = 0;
  std::uint32_t end = 0;
};

/// The region of space a node stands for, bounded by the split planes above it (closed: points
/// on a plane may lie on either side), and its parent.
struct Cell {
  float lo[3];
  float hi[3];
  std::uint32_t parent;
};

/// No node.
constexpr std::uint32_t kNoNode = ~std::uint32_t{0};

/// The arrays one search reads.
struct TreeView {
  const Node* nodes;
  const Cell* cells;
  const float* x;  ///< leaf order, grouped by kLanes
  const float* y;
  const float* z;
  const std::uint32_t* order;  ///< cloud index of each leaf-ordered point
};

/// Squared distances of one group of leaf points from q, each summed x, y, z in this order as
/// everywhere: the lower bound of a cell below is summed the same way from smaller terms, so it
/// never exceeds the distance of a point inside (float addition and multiplication are
/// monotone).
[[gnu::always_inline]] inline void group_distances(const TreeView& tree, std::uint32_t at,
                                                   const float* q, Lanes& d) {
  Lanes x, y, z;
  __builtin_memcpy(&x, tree.x + at, sizeof(Lanes));
  __builtin_memcpy(&y, tree.y + at, sizeof(Lanes));
  __builtin_memcpy(&z, tree.z + at, sizeof(Lanes));
  const Lanes dx = x - q[0], dy = y - q[1], dz = z - q[2];
  d = dx * dx + dy * dy + dz * dz;
}

/// out = v with its lanes exchanged in blocks of `span` (4, 2 or 1): lane i takes lane i ^ span.
/// (Vectors by reference: a 32-byte vector passed or returned by value changes the ABI between
/// the clones.)
template <int span, class Vector>
[[gnu::always_inline]] inline void exchange_lanes(const Vector& v, Vector& out) {
#if defined(__clang__)
  if constexpr (span == 4) {
    out = __builtin_shufflevector(v, v, 4, 5, 6, 7, 0, 1, 2, 3);
  } else if constexpr (span == 2) {
    out = __builtin_shufflevector(v, v, 2, 3, 0, 1, 6, 7, 4, 5);
  } else {
    out = __builtin_shufflevector(v, v, 1, 0, 3, 2, 5, 4, 7, 6);
  }
#else
  if constexpr (span == 4) {
    out = __builtin_shuffle(v, LaneIndices{4, 5, 6, 7, 0, 1, 2, 3});
  } else if constexpr (span == 2) {
    out = __builtin_shuffle(v, LaneIndices{2, 3, 0, 1, 6, 7, 4, 5});
  } else {
    out = __builtin_shuffle(v, LaneIndices{1, 0, 3, 2, 5, 4, 7, 6});
  }
#endif
}

/// The least of eight lanes (Lanes or LaneIndices; none NaN: a NaN lane may come out as the
/// least), halving them three times: a tree of three dependent minima, not a chain of seven.
template <class Vector>
[[gnu::always_inline]] inline auto lane_minimum(const Vector& lanes) {
  Vector v = lanes, folded;
  exchange_lanes<4>(v, folded);
  v = folded < v ? folded : v;
  exchange_lanes<2>(v, folded);
  v = folded < v ? folded : v;
  exchange_lanes<1>(v, folded);
  v = folded < v ? folded : v;
  return v[0];
}

/// The one nearest point strictly closer than a bound; ties keep the point met first.
struct NearestResult {
  static constexpr std::uint32_t kNone = ~std::uint32_t{0};
  float worst;
  std::uint32_t position = kNone;  ///< in leaf order
  /// Leaf points [begin, end) (at most kLeafSize): the smallest distance over the leaf, then the
  /// first point at it, which is what visiting the points one by one with "strictly closer"
  /// keeps.
  [[gnu::always_inline]] inline void add_leaf(const TreeView& tree, std::uint32_t begin,
                                              std::uint32_t end, const float* q) {
    constexpr float kInf = std::numeric_limits<float>::infinity();
    Lanes d[kLeafGroups];
    // Two running minima, over the even and the odd groups, so that the minima of the groups
    // do not form one chain.
    Lanes even = Lanes{} + kInf, odd = even;
    const std::uint32_t groups = (end - begin + kLanes - 1) / kLanes;
    for (std::uint32_t g = 0; g < groups; ++g) {
      group_distances(tree, begin + g * kLanes, q, d[g]);
      if (g % 2 == 0) {
        even = d[g] < even ? d[g] : even;  // a NaN distance never wins
      } else {
        odd = d[g] < odd ? d[g] : odd;
      }
    }
    Lanes smallest = odd < even ? odd : even;
    const float best = lane_minimum(smallest);
    if (!(best < worst)) return;
    LaneIndices lanes;
    for (std::uint32_t lane = 0; lane < kLanes; ++lane)
      lanes[lane] = static_cast<std::int32_t>(lane);
    LaneIndices first = LaneIndices{} + std::numeric_limits<std::int32_t>::max();
    for (std::uint32_t g = 0; g < groups; ++g) {
      const LaneIndices here = lanes + static_cast<std::int32_t>(g * kLanes);
      const LaneIndices candidate = d[g] == best ? here : first;
      first = candidate < first ? candidate : first;
    }
    const std::int32_t lane = lane_minimum(first);
    worst = best;
    position = begin + static_cast<std::uint32_t>(lane);
  }
};

/// The k nearest points (strictly closer than the k-th found so far), nearest first; ties keep
/// the point met first.
/// With a bound, only points strictly closer than it are kept: when at least k are, the same k
/// points as without (a search prunes only cells no closer than the bound, and meets the points
/// it keeps in the same order).
struct KnnResult {
  KnnResult(int count_wanted, std::uint32_t* out_indices, float* out_distances,
            float bound = std::numeric_limits<float>::infinity())
      : k(count_wanted), worst(bound), indices(out_indices), distances(out_distances) {}
  int k;
  int count = 0;
  float worst;
  std::uint32_t* indices;
  float* distances;
  [[gnu::always_inline]] inline void add_leaf(const TreeView& tree, std::uint32_t begin,
                                              std::uint32_t end, const float* q) {
    // The kept points in locals that nothing else can point at: the stores of an insertion then
    // do not force the bound, the count and the arrays' addresses to be read again.
    float* __restrict kept_distances = distances;
    std::uint32_t* __restrict kept_indices = indices;
    int kept = count;
    float bound = worst;
    for (std::uint32_t at = begin; at < end; at += kLanes) {
      Lanes d;
      group_distances(tree, at, q, d);
      // Most groups hold no point closer than the k-th kept: one test of the group's least
      // distance (padding lanes are at infinity, a NaN distance never wins) skips them.
      const Lanes bounds = Lanes{} + bound;
      if (!(lane_minimum(d < bounds ? d : bounds) < bound)) continue;
      const std::uint32_t n = std::min(kLanes, end - at);
      for (std::uint32_t lane = 0; lane < n; ++lane) {
        const float distance = d[lane];
        if (!(distance < bound)) continue;
        int j = kept < k ? kept++ : k - 1;
        for (; j > 0 && kept_distances[j - 1] > distance; --j) {
          kept_distances[j] = kept_distances[j - 1];
          kept_indices[j] = kept_indices[j - 1];
        }
        kept_distances[j] = distance;
        kept_indices[j] = tree.order[at + lane];
        if (kept == k) bound = kept_distances[k - 1];
      }
    }
    count = kept;
    worst = bound;
  }
};

/// Visits the leaves of the subtree at `node` whose cells may hold a point closer than
/// result.worst, nearer child first: a far child is visited after the near one, if its cell (at
/// least sqrt(off . off) from q, off being q's offsets beyond the subtree's cell, `start_off`, and
/// beyond the split planes on the path) is still closer than the worst point kept. Returns the
/// first leaf visited (the one whose cell holds q when q lies in the subtree's cell).
template <class Result>
[[gnu::always_inline]] inline std::uint32_t search(const TreeView& tree, std::uint32_t node,
                                                   const float* start_off, const float* q,
                                                   Result& result) {
  struct Pending {
    std::uint32_t node;
    float bound;  ///< off . off of its cell
    float off[3];
  };
  Pending stack[kMaxDepth];
  int top = 0;
  std::uint32_t first_leaf = kNoNode;
  float off[3] = {start_off[0], start_off[1], start_off[2]};
  for (;;) {
    const Node* n = tree.nodes + node;
    while (n->dim != kLeaf) {
      const float diff = q[n->dim] - n->split;
      const std::uint32_t near = diff < 0.0f ? node + 1 : n->right_or_begin;
      Pending& far = stack[top++];
      far.node = diff < 0.0f ? n->right_or_begin : node + 1;
      far.off[0] = off[0];
      far.off[1] = off[1];
      far.off[2] = off[2];
      far.off[n->dim] = diff;  // the far cell lies beyond the split plane
      far.bound = far.off[0] * far.off[0] + far.off[1] * far.off[1] + far.off[2] * far.off[2];
      node = near;
      n = tree.nodes + node;
    }
    if (first_leaf == kNoNode) first_leaf = node;
    result.add_leaf(tree, n->right_or_begin, n->end, q);
    for (;;) {
      if (top == 0) return first_leaf;
      const Pending& next = stack[--top];
      if (next.bound < result.worst) {
        node = next.node;
        off[0] = next.off[0];
        off[1] = next.off[1];
        off[2] = next.off[2];
        break;
      }
    }
  }
}

/// The whole tree.
template <class Result>
[[gnu::always_inline]] inline void search(const TreeView& tree, const float* q, Result& result) {
  constexpr float kZero[3] = {0.0f, 0.0f, 0.0f};
  search(tree, 0, kZero, q, result);
}

/// q's offsets beyond a cell [lo, hi] along each axis (0 inside it): the same differences the
/// descent from the root forms against the cell's bounding split planes.
[[gnu::always_inline]] inline void offsets(const Cell& cell, const float* q, float* off) {
  for (int d = 0; d < 3; ++d) {
    const float below = q[d] - cell.lo[d], above = q[d] - cell.hi[d];
    off[d] = below < 0.0f ? below : (above > 0.0f ? above : 0.0f);
  }
}

/// Whether q lies in the closed cell.
[[gnu::always_inline]] inline bool inside(const Cell& cell, const float* q) {
  return q[0] >= cell.lo[0] && q[0] <= cell.hi[0] && q[1] >= cell.lo[1] && q[1] <= cell.hi[1] &&
         q[2] >= cell.lo[2] && q[2] <= cell.hi[2];
}

/// Whether every point strictly closer to q than sqrt(worst) lies in the closed cell (q in it).
[[gnu::always_inline]] inline bool ball_inside(const Cell& cell, const float* q, float worst) {
  for (int d = 0; d < 3; ++d) {
    const float below = q[d] - cell.lo[d], above = cell.hi[d] - q[d];
    if (!(below * below >= worst && above * above >= worst)) return false;
  }
  return true;
}

/// One search of a run of queries, started from `leaf`, the leaf whose cell held the query before
/// (set to the one holding q): climb to the lowest cell holding q, search it, then climb on,
/// searching each sibling cell still closer than the worst point kept, until the ball of that
/// radius lies inside the cell searched. The distances kept are the top-down search's exactly;
/// among points at the very same distance another one may be kept.
template <class Result>
[[gnu::always_inline]] inline void search_from(const TreeView& tree, const float* q,
                                               std::uint32_t& leaf, Result& result) {
  std::uint32_t node = leaf;
  while (node != 0 && !inside(tree.cells[node], q)) node = tree.cells[node].parent;
  constexpr float kZero[3] = {0.0f, 0.0f, 0.0f};
  leaf = search(tree, node, kZero, q, result);
  while (node != 0 && !ball_inside(tree.cells[node], q, result.worst)) {
    const std::uint32_t parent = tree.cells[node].parent;
    const std::uint32_t sibling =
        node == parent + 1 ? tree.nodes[parent].right_or_begin : parent + 1;
    float off[3];
    offsets(tree.cells[sibling], q, off);
    if (off[0] * off[0] + off[1] * off[1] + off[2] * off[2] < result.worst)
      search(tree, sibling, off, q, result);
    node = parent;
  }
}

/// The nearest point of one query (search from the root).
CARAT_MULTIVERSION_WIDE void search_nearest(const TreeView& tree, const float* q,
                                            NearestResult& result) {
  search(tree, q, result);
}

/// The k nearest points of one query (search from the root).
CARAT_MULTIVERSION_WIDE void search_knn(const TreeView& tree, const float* q, KnnResult& result) {
  search(tree, q, result);
}

/// The k nearest points of each of a run of queries (k slots a query in indices and distances;
/// found[q] of them filled). Each search is bounded by what the one before found: the previous
/// query's k points are k points within the farthest of them from q, so no point beyond that
/// can be among q's k nearest (the bound is raised by 1e-5 of itself over rounding). A search
/// that keeps fewer than k (a query or a point is not finite) is run again without it. The
/// answers are the single-query search's exactly, ties included: the bounded search prunes only
/// cells no closer than its bound and meets the points it keeps in the same order.
CARAT_MULTIVERSION_WIDE void search_knn_run(const TreeView& tree, const Eigen::Vector3f* points,
                                            const Eigen::Vector3f* queries, std::size_t count,
                                            int k, std::size_t available, std::uint32_t* indices,
                                            float* distances, int* found) {
  const int wanted =
      static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(k), available));
  constexpr float kInf = std::numeric_limits<float>::infinity();
  const auto slots = static_cast<std::size_t>(k);
  for (std::size_t q = 0; q < count; ++q) {
    std::uint32_t* out_indices = indices + q * slots;
    float* out_distances = distances + q * slots;
    float bound = kInf;
    if (q > 0 && found[q - 1] == k) {
      const std::uint32_t* previous = indices + (q - 1) * slots;
      float farthest = 0.0f;
      for (std::size_t j = 0; j < slots; ++j) {
        const Eigen::Vector3f d = points[previous[j]] - queries[q];
        const float squared = d.x() * d.x() + d.y() * d.y() + d.z() * d.z();
        farthest = squared > farthest ? squared : farthest;  // a NaN distance leaves no bound
        if (!(squared <= farthest)) farthest = kInf;
      }
      bound = farthest * (1.0f + 1e-5f) + std::numeric_limits<float>::denorm_min();
    }
    KnnResult result(k, out_indices, out_distances, bound);
    search(tree, queries[q].data(), result);
    if (result.count < wanted && bound < kInf) {
      result = KnnResult(k, out_indices, out_distances);
      search(tree, queries[q].data(), result);
    }
    found[q] = result.count;
  }
}

/// Nearest points (leaf order) and squared distances of a run of queries.
CARAT_MULTIVERSION_WIDE void search_nearest_run(const TreeView& tree,
                                                const Eigen::Vector3f* queries, std::size_t count,
                                                float bound, std::uint32_t* positions,
                                                float* distances) {
  std::uint32_t leaf = 0;
  for (std::size_t k = 0; k < count; ++k) {
    NearestResult result{bound};
    search_from(tree, queries[k].data(), leaf, result);
    positions[k] = result.position;
    distances[k] = result.worst;
  }
}

}  // namespace

struct KdTree::Impl {
  explicit Impl(const PointCloud& cloud);

  /// Splits points [begin, end) (of `order`) into a subtree; returns its root node.
  std::uint32_t build(std::uint32_t begin, std::uint32_t end);

  TreeView view() const {
    return {nodes.data(), cells.data(), x.data(), y.data(), z.data(), order.data()};
  }

  const PointCloud& cloud;
  std::vector<Node> nodes;
  std::vector<Cell> cells;           ///< of each node
  std::vector<std::uint32_t> order;  ///< cloud index of the j-th point in leaf order
  std::vector<float> x, y, z;        ///< positions in leaf order, grouped by kLanes
};

KdTree::Impl::Impl(const PointCloud& positions) : cloud(positions) {
  const auto n = static_cast<std::uint32_t>(cloud.size());
  if (n == 0) return;
  order.resize(n);
  std::iota(order.begin(), order.end(), 0u);
  nodes.reserve(2 * (n / kLeafSize + 1));
  build(0, n);
  // Cells from the root down (a node's children come after it).
  constexpr float kInf = std::numeric_limits<float>::infinity();
  cells.resize(nodes.size());
  cells[0] = {{-kInf, -kInf, -kInf}, {kInf, kInf, kInf}, 0};
  for (std::uint32_t i = 0; i < nodes.size(); ++i) {
    const Node& node = nodes[i];
    if (node.dim == kLeaf) continue;
    Cell left = cells[i], right = cells[i];
    left.hi[node.dim] = node.split;
    right.lo[node.dim] = node.split;
    left.parent = right.parent = i;
    cells[i + 1] = left;
    cells[node.right_or_begin] = right;
  }
  // Lay the leaves out in whole groups of lanes, padded with points at infinity.
  std::uint32_t lanes = 0;
  for (const Node& node : nodes)
    if (node.dim == kLeaf) lanes += (node.end - node.right_or_begin + kLanes - 1) / kLanes * kLanes;
  x.assign(lanes, kInf);
  y.assign(lanes, kInf);
  z.assign(lanes, kInf);
  std::vector<std::uint32_t> grouped(lanes, ~std::uint32_t{0});
  std::uint32_t at = 0;
  for (Node& node : nodes) {
    if (node.dim != kLeaf) continue;
    const std::uint32_t begin = node.right_or_begin, count = node.end - begin;
    for (std::uint32_t j = 0; j < count; ++j) {
      const Eigen::Vector3f& p = cloud.points[order[begin + j]];
      x[at + j] = p.x();
      y[at + j] = p.y();
      z[at + j] = p.z();
      grouped[at + j] = order[begin + j];
    }
    node.right_or_begin = at;
    node.end = at + count;
    at += (count + kLanes - 1) / kLanes * kLanes;
  }
  order = std::move(grouped);
}

std::uint32_t KdTree::Impl::build(std::uint32_t begin, std::uint32_t end) {
  const auto node = static_cast<std::uint32_t>(nodes.size());
  nodes.emplace_back();
  Eigen::Array3f lo = cloud.points[order[begin]].array(), hi = lo;
  if (end - begin > kLeafSize) {
    for (std::uint32_t j = begin + 1; j < end; ++j) {
      lo = lo.min(cloud.points[order[j]].array());
      hi = hi.max(cloud.points[order[j]].array());
    }
  }
  Eigen::Index dim = 0;
  const float extent = (hi - lo).maxCoeff(&dim);
  if (end - begin <= kLeafSize) {
    nodes[node].right_or_begin = begin;
    nodes[node].end = end;
    return node;
  }
  // Points all at one position (or not finite) are halved all the same, so that no leaf holds
  // more than kLeafSize: they compare equal to the split and may lie on either side of it.
  if (!(extent > 0.0f)) dim = 0;
  const std::uint32_t middle = begin + (end - begin) / 2;
  // A NaN coordinate sorts as +infinity, so that the order stays a strict weak order.
  const auto coordinate = [&](std::uint32_t i) {
    const float c = cloud.points[i][dim];
    return std::isnan(c) ? std::numeric_limits<float>::infinity() : c;
  };
  std::nth_element(order.begin() + begin, order.begin() + middle, order.begin() + end,
                   [&](std::uint32_t a, std::uint32_t b) { return coordinate(a) < coordinate(b); });
  const float split = coordinate(order[middle]);
  build(begin, middle);
  const std::uint32_t right = build(middle, end);
  nodes[node].split = split;
  nodes[node].dim = static_cast<std::uint32_t>(dim);
  nodes[node].right_or_begin = right;
  return node;
}

KdTree::KdTree(const PointCloud& cloud) : impl_(std::make_unique<Impl>(cloud)) {}
KdTree::~KdTree() = default;

int KdTree::knn(const Eigen::Vector3f& query, int k, std::uint32_t* indices,
                float* squared_distances) const {
  if (impl_->nodes.empty() || k <= 0) return 0;
  KnnResult result(k, indices, squared_distances);
  search_knn(impl_->view(), query.data(), result);
  return result.count;
}

void KdTree::knn(std::span<const Eigen::Vector3f> queries, int k, std::uint32_t* indices,
                 float* squared_distances, int* found) const {
  if (impl_->nodes.empty() || k <= 0) {
    std::fill_n(found, queries.size(), 0);
    return;
  }
  search_knn_run(impl_->view(), impl_->cloud.points.data(), queries.data(), queries.size(), k,
                 impl_->cloud.size(), indices, squared_distances, found);
}

std::size_t KdTree::memory_bytes() const {
  return sizeof(Impl) + impl_->nodes.capacity() * sizeof(Node) +
         impl_->cells.capacity() * sizeof(Cell) + impl_->order.capacity() * sizeof(std::uint32_t) +
         (impl_->x.capacity() + impl_->y.capacity() + impl_->z.capacity()) * sizeof(float);
}

bool KdTree::nearest(const Eigen::Vector3f& query, std::uint32_t* index,
                     float* squared_distance) const {
  return knn(query, 1, index, squared_distance) == 1;
}

namespace {

/// The strictly-closer-than bound that makes a maximum squared distance (>= 0) itself count:
/// the next float up (for a float below infinity, the next bit pattern; a libm call costs more
/// than a query's leaf).
float inclusive_bound(float max_squared_distance) {
  if (max_squared_distance == 0.0f) return std::numeric_limits<float>::denorm_min();  // also -0
  if (max_squared_distance < std::numeric_limits<float>::infinity())
    return std::bit_cast<float>(std::bit_cast<std::uint32_t>(max_squared_distance) + 1u);
  return max_squared_distance;
}

}  // namespace

void KdTree::nearest_within(std::span<const Eigen::Vector3f> queries, float max_squared_distance,
                            std::uint32_t* indices, float* squared_distances) const {
  if (impl_->nodes.empty() || !(max_squared_distance >= 0.0f)) {
    std::fill_n(indices, queries.size(), kNotFound);
    std::fill_n(squared_distances, queries.size(), std::numeric_limits<float>::infinity());
    return;
  }
  search_nearest_run(impl_->view(), queries.data(), queries.size(),
                     inclusive_bound(max_squared_distance), indices, squared_distances);
  for (std::size_t k = 0; k < queries.size(); ++k) {
    if (indices[k] == NearestResult::kNone) {
      indices[k] = kNotFound;
      squared_distances[k] = std::numeric_limits<float>::infinity();
    } else {
      indices[k] = impl_->order[indices[k]];
    }
  }
}

bool KdTree::nearest_within(const Eigen::Vector3f& query, float max_squared_distance,
                            std::uint32_t* index, float* squared_distance) const {
  if (impl_->nodes.empty() || !(max_squared_distance >= 0.0f)) return false;
  NearestResult result{inclusive_bound(max_squared_distance)};
  search_nearest(impl_->view(), query.data(), result);
  if (result.position == NearestResult::kNone) return false;
  *index = impl_->order[result.position];
  *squared_distance = result.worst;
  return true;
}

}  // namespace carat
