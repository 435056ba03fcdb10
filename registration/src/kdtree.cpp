#include "carat/registration/kdtree.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <type_traits>

namespace carat {
namespace {

/// Most points a leaf holds.
constexpr std::uint32_t kLeafSize = 20;
/// Node::dim of a leaf.
constexpr std::uint32_t kLeaf = 3;

/// A position in leaf order, padded to 16 bytes so that a leaf is one contiguous run.
struct alignas(16) LeafPoint {
  float x, y, z, pad;
};

/// A tree node. Inner: the points with coordinate `dim` below `split` are in the left child
/// (the next node), those above in the right child (node `right_or_begin`), those equal in
/// either.
/// Leaf: points [begin, end) of the leaf-ordered arrays.
struct Node {
  float split = 0.0f;
  std::uint32_t dim = kLeaf;
  std::uint32_t right_or_begin = 0;
  std::uint32_t end = 0;
};

/// Squared distance, summed x, y, z in this order everywhere: the lower bound of a cell below is
/// summed the same way from smaller terms, so it never exceeds the distance of a point inside
/// (float addition and multiplication are monotone).
[[gnu::always_inline]] inline float squared_distance(const LeafPoint& p, const float* q) {
  const float dx = p.x - q[0], dy = p.y - q[1], dz = p.z - q[2];
  return dx * dx + dy * dy + dz * dz;
}

/// The one nearest point strictly closer than a bound; ties keep the point met first.
struct NearestResult {
  static constexpr std::uint32_t kNone = ~std::uint32_t{0};
  float worst;
  std::uint32_t position = kNone;  ///< in leaf order
  /// Leaf points [begin, end), without a branch per point.
  void add_leaf(const LeafPoint* points, std::uint32_t begin, std::uint32_t end, const float* q) {
    float best = worst;
    std::uint32_t at = position;
    for (std::uint32_t j = begin; j < end; ++j) {
      const float d = squared_distance(points[j], q);
      const bool closer = d < best;
      at = closer ? j : at;
      best = closer ? d : best;
    }
    worst = best;
    position = at;
  }
};

/// The k nearest points (strictly closer than the k-th found so far), nearest first; ties keep
/// the point met first.
struct KnnResult {
  KnnResult(int count_wanted, std::uint32_t* out_indices, float* out_distances)
      : k(count_wanted), indices(out_indices), distances(out_distances) {}
  int k;
  int count = 0;
  float worst = std::numeric_limits<float>::infinity();
  std::uint32_t* indices;
  float* distances;
  void add_leaf(const LeafPoint* points, std::uint32_t begin, std::uint32_t end, const float* q,
                const std::uint32_t* order) {
    for (std::uint32_t j = begin; j < end; ++j) add(squared_distance(points[j], q), order[j]);
  }
  void add(float d, std::uint32_t i) {
    if (!(d < worst)) return;
    int j = count < k ? count++ : k - 1;
    for (; j > 0 && distances[j - 1] > d; --j) {
      distances[j] = distances[j - 1];
      indices[j] = indices[j - 1];
    }
    distances[j] = d;
    indices[j] = i;
    if (count == k) worst = distances[k - 1];
  }
};

}  // namespace

struct KdTree::Impl {
  explicit Impl(const PointCloud& cloud);

  /// Splits points [begin, end) (of `order`) into a subtree; returns its root node.
  std::uint32_t build(std::uint32_t begin, std::uint32_t end);

  /// Visits the subtree at `node` whose cell lies at least sqrt(off . off) from q.
  template <class Result>
  void search(std::uint32_t node, const float* q, std::array<float, 3>& off, Result& result) const {
    const Node& n = nodes[node];
    if (n.dim == kLeaf) {
      if constexpr (std::is_same_v<Result, NearestResult>) {
        result.add_leaf(points.data(), n.right_or_begin, n.end, q);
      } else {
        result.add_leaf(points.data(), n.right_or_begin, n.end, q, order.data());
      }
      return;
    }
    const float diff = q[n.dim] - n.split;
    const std::uint32_t near = diff < 0.0f ? node + 1 : n.right_or_begin;
    const std::uint32_t far = diff < 0.0f ? n.right_or_begin : node + 1;
    search(near, q, off, result);
    const float saved = off[n.dim];
    off[n.dim] = diff;  // the far cell lies beyond the split plane
    if (off[0] * off[0] + off[1] * off[1] + off[2] * off[2] < result.worst)
      search(far, q, off, result);
    off[n.dim] = saved;
  }

  template <class Result>
  void search(const Eigen::Vector3f& query, Result& result) const {
    std::array<float, 3> off{0.0f, 0.0f, 0.0f};
    search(0, query.data(), off, result);
  }

  const PointCloud& cloud;
  std::vector<Node> nodes;
  std::vector<std::uint32_t> order;  ///< cloud index of the j-th point in leaf order
  std::vector<LeafPoint> points;     ///< positions in leaf order
};

KdTree::Impl::Impl(const PointCloud& positions) : cloud(positions) {
  const auto n = static_cast<std::uint32_t>(cloud.size());
  if (n == 0) return;
  order.resize(n);
  std::iota(order.begin(), order.end(), 0u);
  nodes.reserve(2 * (n / kLeafSize + 1));
  build(0, n);
  points.resize(n);
  for (std::uint32_t j = 0; j < n; ++j) {
    const Eigen::Vector3f& p = cloud.points[order[j]];
    points[j] = {p.x(), p.y(), p.z(), 0.0f};
  }
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
  if (end - begin <= kLeafSize || !(extent > 0.0f)) {  // small, or all points at one position
    nodes[node].right_or_begin = begin;
    nodes[node].end = end;
    return node;
  }
  const std::uint32_t middle = begin + (end - begin) / 2;
  // A NaN coordinate sorts as +infinity, so that the order stays a strict weak order.
  const auto coordinate = [&](std::uint32_t i) {
    const float x = cloud.points[i][dim];
    return std::isnan(x) ? std::numeric_limits<float>::infinity() : x;
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
  impl_->search(query, result);
  return result.count;
}

std::size_t KdTree::memory_bytes() const {
  return sizeof(Impl) + impl_->tree.usedMemory(impl_->tree);
}

bool KdTree::nearest(const Eigen::Vector3f& query, std::uint32_t* index,
                     float* squared_distance) const {
  return knn(query, 1, index, squared_distance) == 1;
}

bool KdTree::nearest_within(const Eigen::Vector3f& query, float max_squared_distance,
                            std::uint32_t* index, float* squared_distance) const {
  if (impl_->nodes.empty() || !(max_squared_distance >= 0.0f)) return false;
  // Strictly-closer-than bound: the next float up makes the maximum distance itself count.
  NearestResult result{
      std::nextafter(max_squared_distance, std::numeric_limits<float>::infinity())};
  impl_->search(query, result);
  if (result.position == NearestResult::kNone) return false;
  *index = impl_->order[result.position];
  *squared_distance = result.worst;
  return true;
}

}  // namespace carat
