#include "carat/registration/kdtree.hpp"

#include <cmath>
#include <limits>
#include <nanoflann.hpp>

namespace carat {
namespace {

/// nanoflann's dataset adaptor over a PointCloud.
struct CloudAdaptor {
  const PointCloud& cloud;
  std::size_t kdtree_get_point_count() const { return cloud.points.size(); }
  float kdtree_get_pt(std::size_t i, std::size_t dim) const {
    return cloud.points[i][static_cast<Eigen::Index>(dim)];
  }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};

/// nanoflann result set for the one nearest point strictly closer than a starting bound.
class NearestWithinBound {
 public:
  explicit NearestWithinBound(float bound) : worst_(bound) {}
  bool addPoint(float squared_distance, std::uint32_t index) {
    if (squared_distance < worst_) {
      worst_ = squared_distance;
      index_ = index;
      found_ = true;
    }
    return true;  // keep searching: a closer point may still come
  }
  float worstDist() const { return worst_; }
  bool full() const { return found_; }
  bool found() const { return found_; }
  std::uint32_t index() const { return index_; }

 private:
  float worst_;
  std::uint32_t index_ = 0;
  bool found_ = false;
};

using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, CloudAdaptor>,
                                                 CloudAdaptor, 3, std::uint32_t>;

}  // namespace

struct KdTree::Impl {
  explicit Impl(const PointCloud& cloud)
      : adaptor{cloud}, tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10)) {}
  CloudAdaptor adaptor;
  Tree tree;
};

KdTree::KdTree(const PointCloud& cloud) : impl_(std::make_unique<Impl>(cloud)) {}
KdTree::~KdTree() = default;

int KdTree::knn(const Eigen::Vector3f& query, int k, std::uint32_t* indices,
                float* squared_distances) const {
  if (impl_->adaptor.cloud.points.empty() || k <= 0) return 0;
  return static_cast<int>(
      impl_->tree.knnSearch(query.data(), static_cast<std::size_t>(k), indices, squared_distances));
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
  if (impl_->adaptor.cloud.points.empty() || !(max_squared_distance >= 0.0f)) return false;
  // Strictly-closer-than bound: the next float up makes the maximum distance itself count.
  NearestWithinBound result(
      std::nextafter(max_squared_distance, std::numeric_limits<float>::infinity()));
  impl_->tree.findNeighbors(result, query.data(), nanoflann::SearchParams());
  if (!result.found()) return false;
  *index = result.index();
  *squared_distance = result.worstDist();
  return true;
}

}  // namespace carat
