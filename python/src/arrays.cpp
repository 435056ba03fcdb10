#include "arrays.hpp"

#include <cmath>
#include <cstring>
#include <memory>
#include <utility>

namespace carat::python {

py::array_t<double, py::array::c_style> as_float64(const py::handle& obj, const std::string& what) {
  if (py::isinstance<py::str>(obj) || py::isinstance<py::bytes>(obj)) {
    throw py::type_error(what + ": expected an array of numbers, got " +
                         std::string(py::str(py::type::of(obj).attr("__name__"))));
  }
  py::array array;
  try {
    array = py::array::ensure(obj);
  } catch (const py::error_already_set&) {
  }
  if (!array) {
    throw py::type_error(what + ": expected an array of numbers, got " +
                         std::string(py::str(py::type::of(obj).attr("__name__"))));
  }
  const char kind = array.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u' && kind != 'b') {
    throw py::type_error(what + ": expected an array of real numbers, got dtype " +
                         std::string(py::str(array.dtype())));
  }
  return py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(array);
}

PointCloud cloud_from_array(const py::handle& obj, const std::string& what) {
  PointCloud cloud;
  py::array checked;
  const py::array ensured = py::array::ensure(obj);
  if (ensured && ensured.dtype().is(py::dtype::of<float>()) &&
      (ensured.flags() & py::array::c_style) && ensured.ndim() == 2 && ensured.shape(1) == 3) {
    checked = ensured;  // float32, N x 3, contiguous: the layout of PointCloud::points
  } else {
    checked = as_float64(obj, what);
  }
  if (checked.ndim() != 2 || (checked.shape(1) != 3 && checked.shape(1) != 4)) {
    std::string shape;
    for (py::ssize_t d = 0; d < checked.ndim(); ++d) {
      shape += (d ? ", " : "") + std::to_string(checked.shape(d));
    }
    throw py::value_error(what + ": expected an N x 3 array of points, got shape (" + shape + ")");
  }
  const auto n = static_cast<std::size_t>(checked.shape(0));
  cloud.points.resize(n);
  if (checked.dtype().is(py::dtype::of<float>())) {
    std::memcpy(static_cast<void*>(cloud.points.data()), checked.data(), n * 3 * sizeof(float));
  } else {
    const auto* values = static_cast<const double*>(checked.data());
    const auto stride = static_cast<std::size_t>(checked.shape(1));
    for (std::size_t i = 0; i < n; ++i) {
      const double* row = values + i * stride;
      cloud.points[i] = Eigen::Vector3d(row[0], row[1], row[2]).cast<float>();
    }
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (!cloud.points[i].allFinite()) {
      throw py::value_error(what + ": point " + std::to_string(i) +
                            " is not finite (NaN, Inf or beyond float32)");
    }
  }
  return cloud;
}

py::array_t<float> array_from_cloud(PointCloud&& cloud) {
  auto* points = new std::vector<Eigen::Vector3f>(std::move(cloud.points));
  py::capsule owner(points, [](void* p) { delete static_cast<std::vector<Eigen::Vector3f>*>(p); });
  return py::array_t<float>(
      {static_cast<py::ssize_t>(points->size()), py::ssize_t{3}},
      {static_cast<py::ssize_t>(sizeof(Eigen::Vector3f)), static_cast<py::ssize_t>(sizeof(float))},
      points->empty() ? nullptr : points->front().data(), owner);
}

py::array_t<double> covariances_array(const PointCloud& cloud) {
  const auto n = static_cast<py::ssize_t>(cloud.covariances.size());
  py::array_t<double> out({n, py::ssize_t{3}, py::ssize_t{3}});
  double* data = out.mutable_data();
  for (py::ssize_t i = 0; i < n; ++i) {
    Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(data + 9 * i) =
        cloud.covariance(static_cast<std::size_t>(i));
  }
  return out;
}

namespace {

Eigen::Isometry3d checked_pose(const double* m, const std::string& what) {
  for (int k = 0; k < 16; ++k) {
    if (!std::isfinite(m[k])) throw py::value_error(what + ": the pose is not finite");
  }
  const Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>> M(m);
  if ((M.row(3) - Eigen::RowVector4d(0.0, 0.0, 0.0, 1.0)).cwiseAbs().maxCoeff() > 1e-9) {
    throw py::value_error(what + ": the last row of a 4 x 4 pose must be (0, 0, 0, 1)");
  }
  const Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-6 || R.determinant() <= 0.0) {
    throw py::value_error(what +
                          ": the rotation block is not a rotation (orthonormal to 1e-6, "
                          "determinant +1)");
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(R).normalized().toRotationMatrix();
  T.translation() = M.topRightCorner<3, 1>();
  return T;
}

}  // namespace

Eigen::Isometry3d pose_from_array(const py::handle& obj, const std::string& what) {
  const auto array = as_float64(obj, what);
  if (array.ndim() != 2 || array.shape(0) != 4 || array.shape(1) != 4) {
    throw py::value_error(what + ": expected a 4 x 4 pose");
  }
  return checked_pose(array.data(), what);
}

py::array_t<double> array_from_pose(const Eigen::Isometry3d& T) {
  py::array_t<double> out({py::ssize_t{4}, py::ssize_t{4}});
  Eigen::Map<Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(out.mutable_data()) = T.matrix();
  return out;
}

std::vector<Eigen::Isometry3d> poses_from_array(const py::handle& obj, const std::string& what) {
  const auto array = as_float64(obj, what);
  if (array.ndim() != 3 || array.shape(1) != 4 || array.shape(2) != 4) {
    throw py::value_error(what + ": expected an N x 4 x 4 array of poses");
  }
  std::vector<Eigen::Isometry3d> poses(static_cast<std::size_t>(array.shape(0)));
  for (std::size_t i = 0; i < poses.size(); ++i) {
    poses[i] = checked_pose(array.data() + 16 * i, what + "[" + std::to_string(i) + "]");
  }
  return poses;
}

int neighbors_argument(int neighbors) {
  if (neighbors < 4 || neighbors > 1000) {
    throw py::value_error("neighbors: must be in [4, 1000], got " + std::to_string(neighbors));
  }
  return neighbors;
}

int threads_argument(int threads) {
  if (threads < 1) throw py::value_error("threads: must be >= 1, got " + std::to_string(threads));
  return threads;
}

py::array_t<double> array_from_poses(std::span<const Eigen::Isometry3d> poses) {
  py::array_t<double> out({static_cast<py::ssize_t>(poses.size()), py::ssize_t{4}, py::ssize_t{4}});
  for (std::size_t i = 0; i < poses.size(); ++i) {
    Eigen::Map<Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(out.mutable_data() + 16 * i) =
        poses[i].matrix();
  }
  return out;
}

}  // namespace carat::python
