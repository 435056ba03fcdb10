#include "carat/registration/point_cloud.hpp"

namespace carat {

Eigen::Matrix3d PointCloud::covariance(std::size_t i) const {
  const auto& c = covariances[i];
  Eigen::Matrix3d C;
  C << c[0], c[1], c[2], c[1], c[3], c[4], c[2], c[4], c[5];
  return C;
}

void PointCloud::set_covariance(std::size_t i, const Eigen::Matrix3d& C) {
  covariances[i] << static_cast<float>(C(0, 0)), static_cast<float>(C(0, 1)),
      static_cast<float>(C(0, 2)), static_cast<float>(C(1, 1)), static_cast<float>(C(1, 2)),
      static_cast<float>(C(2, 2));
}

std::size_t PointCloud::memory_bytes() const {
  return points.size() * sizeof(Eigen::Vector3f) +
         covariances.size() * sizeof(Eigen::Matrix<float, 6, 1>);
}

}  // namespace carat
