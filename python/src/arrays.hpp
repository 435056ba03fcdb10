#pragma once

/// numpy <-> carat conversions of the Python module: point arrays, poses and trajectories, with
/// the checks that turn a wrong dtype, shape or value into a Python exception naming the argument
/// (and the thread-count check every call shares).

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <span>
#include <string>
#include <vector>

#include "carat/registration/point_cloud.hpp"

namespace carat::python {

namespace py = pybind11;

/// A C-contiguous float64 array of `obj` (no copy when it already is one); ValueError naming
/// `what` when it cannot be converted (strings, objects, complex numbers).
py::array_t<double, py::array::c_style> as_float64(const py::handle& obj, const std::string& what);

/// A point cloud from an N x 3 (or N x 4, the fourth column ignored) array of numbers, in
/// metres; ValueError naming `what` for another shape or a non-finite row (naming the row).
PointCloud cloud_from_array(const py::handle& obj, const std::string& what);

/// The cloud's positions as an N x 3 float32 array that takes over the cloud's storage (no copy).
py::array_t<float> array_from_cloud(PointCloud&& cloud);

/// An N x 3 x 3 float64 array of the cloud's covariances (metres squared).
py::array_t<double> covariances_array(const PointCloud& cloud);

/// A rigid transform from a 4 x 4 array: finite, last row (0, 0, 0, 1), rotation orthonormal to
/// 1e-6 with determinant +1 (then re-orthonormalized); ValueError naming `what` otherwise.
Eigen::Isometry3d pose_from_array(const py::handle& obj, const std::string& what);

/// The transform as a 4 x 4 float64 array.
py::array_t<double> array_from_pose(const Eigen::Isometry3d& T);

/// Poses from an N x 4 x 4 array (or a sequence of 4 x 4 arrays), each checked as in
/// pose_from_array().
std::vector<Eigen::Isometry3d> poses_from_array(const py::handle& obj, const std::string& what);

/// The poses as an N x 4 x 4 float64 array.
py::array_t<double> array_from_poses(std::span<const Eigen::Isometry3d> poses);

/// `threads` as given; ValueError "threads: must be >= 1, got N" otherwise (carat itself would
/// quietly run on one thread).
int threads_argument(int threads);

/// `neighbors` as given; ValueError unless it is in [4, 1000] (the covariance of each point
/// costs time linear in it, and beyond a few dozen it stops describing the local surface).
int neighbors_argument(int neighbors);

/// `array`, marked read-only (results that are stored in a result object and handed out).
template <typename T>
py::array_t<T> read_only(py::array_t<T> array) {
  array.attr("setflags")(py::arg("write") = false);
  return array;
}

/// A copy of a vector as a 1-D numpy array.
template <typename T>
py::array_t<T> array_from_vector(const std::vector<T>& values) {
  py::array_t<T> out(static_cast<py::ssize_t>(values.size()));
  std::copy(values.begin(), values.end(), out.mutable_data());
  return out;
}

}  // namespace carat::python
