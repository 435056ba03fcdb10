// Point clouds from Python: files, voxel downsampling, covariances and carat.Frame.
#include <pybind11/numpy.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "arrays.hpp"
#include "bindings.hpp"
#include "carat/base/error.hpp"
#include "carat/registration/covariance.hpp"
#include "carat/registration/frame.hpp"
#include "carat/registration/io/kitti_io.hpp"
#include "carat/registration/io/point_cloud_io.hpp"
#include "carat/registration/kdtree.hpp"
#include "carat/registration/voxel_grid.hpp"
#include "frame_list.hpp"
#include "integer_arguments.hpp"
#include "interrupt.hpp"

namespace carat::python {

namespace {

ReadOptions read_options(bool drop_non_finite, std::optional<std::size_t> max_points) {
  ReadOptions options;
  options.drop_non_finite = drop_non_finite;
  if (max_points) options.max_points = *max_points;
  return options;
}

/// An array view of a frame's positions whose base is the Python Frame (no copy, read-only).
py::array_t<float> frame_points(const py::object& self) {
  const auto& frame = self.cast<const Frame&>();
  const auto& points = frame.cloud().points;
  py::array_t<float> out(
      {static_cast<py::ssize_t>(points.size()), py::ssize_t{3}},
      {static_cast<py::ssize_t>(sizeof(Eigen::Vector3f)), static_cast<py::ssize_t>(sizeof(float))},
      points.empty() ? nullptr : points.front().data(), self);
  out.attr("setflags")(py::arg("write") = false);
  return out;
}

std::shared_ptr<Frame> make_frame(const py::handle& points, double voxel_size, int neighbors,
                                  int min_points, int threads, const std::string& name) {
  const PointCloud raw = cloud_from_array(points, name.empty() ? "points" : name);
  PreprocessOptions options;
  options.voxel_size = voxel_size;
  options.covariance_neighbors = neighbors_argument(neighbors);
  options.min_points = min_points;
  options.num_threads = threads_argument(threads);
  auto frame = run_released([&](InterruptCheck&) {
    return preprocess_frame(raw, options, name.empty() ? "points" : name);
  });
  return std::const_pointer_cast<Frame>(frame);
}

}  // namespace

std::vector<std::shared_ptr<const Frame>> frames_from_sequence(const py::handle& obj,
                                                               const std::string& what) {
  if (!py::isinstance<py::sequence>(obj) || py::isinstance<py::str>(obj)) {
    throw py::type_error(what + ": expected a sequence of carat.Frame");
  }
  const auto sequence = py::reinterpret_borrow<py::sequence>(obj);
  std::vector<std::shared_ptr<const Frame>> frames;
  frames.reserve(sequence.size());
  for (std::size_t i = 0; i < sequence.size(); ++i) {
    const py::object item = sequence[i];
    if (!py::isinstance<Frame>(item)) {
      throw py::type_error(what + "[" + std::to_string(i) + "]: expected a carat.Frame, got " +
                           std::string(py::str(py::type::of(item).attr("__name__"))));
    }
    frames.push_back(item.cast<std::shared_ptr<Frame>>());
  }
  return frames;
}

py::list list_from_frames(const std::vector<std::shared_ptr<const Frame>>& frames) {
  py::list out;
  for (const auto& frame : frames) out.append(py::cast(std::const_pointer_cast<Frame>(frame)));
  return out;
}

void bind_clouds(py::module_& m) {
  def_checked(
      m, "read_point_cloud",
      [](const std::filesystem::path& path, const std::string& kitti_format, bool drop_non_finite,
         std::optional<std::size_t> max_points) {
        const KittiFormat format = parse_kitti_format(kitti_format);
        PointCloud cloud = run_released([&](InterruptCheck&) {
          return read_point_cloud(path, format, read_options(drop_non_finite, max_points));
        });
        return array_from_cloud(std::move(cloud));
      },
      py::arg("path"), py::arg("kitti_format") = "xyzi", py::arg("drop_non_finite") = false,
      py::arg("max_points") = py::none(),
      "Reads x, y, z (metres) of a .pcd, .ply or KITTI .bin file (kitti_format 'xyzi' or 'xyz') "
      "as an N x 3 float32 array. Raises carat.Error naming the file for a malformed one.");
  def_checked(
      m, "write_point_cloud",
      [](const std::filesystem::path& path, const py::handle& points, bool ascii,
         const std::string& kitti_format) {
        const PointCloud cloud = cloud_from_array(points, "points");
        const std::string ext = path.extension().string();
        py::gil_scoped_release release;
        if (ext == ".pcd") {
          write_pcd(path, cloud, ascii);
        } else if (ext == ".ply") {
          write_ply(path, cloud, ascii);
        } else if (ext == ".bin") {
          write_kitti_bin(path, cloud, parse_kitti_format(kitti_format));
        } else {
          throw Error(path.string() + ": unsupported file type '" + ext +
                      "' (expected .pcd, .ply or .bin)");
        }
      },
      py::arg("path"), py::arg("points"), py::arg("ascii") = false,
      py::arg("kitti_format") = "xyzi",
      "Writes an N x 3 array as .pcd, .ply (binary unless ascii) or KITTI .bin, atomically.");
  def_checked(
      m, "voxel_downsample",
      [](const py::handle& points, double voxel_size) {
        const PointCloud cloud = cloud_from_array(points, "points");
        PointCloud down =
            run_released([&](InterruptCheck&) { return voxel_downsample(cloud, voxel_size); });
        return array_from_cloud(std::move(down));
      },
      py::arg("points"), py::arg("voxel_size"),
      "Centroids of the occupied voxels of edge voxel_size (metres), ordered by voxel.");
  def_checked(
      m, "estimate_covariances",
      [](const py::handle& points, int neighbors, int threads) {
        PointCloud cloud = cloud_from_array(points, "points");
        CovarianceOptions options;
        options.neighbors = neighbors_argument(neighbors);
        options.num_threads = threads_argument(threads);
        run_released([&](InterruptCheck&) {
          const KdTree tree(cloud);
          estimate_covariances(cloud, tree, options);
        });
        return covariances_array(cloud);
      },
      py::arg("points"), py::arg("neighbors") = 10, py::arg("threads") = 1,
      "GICP covariances (N x 3 x 3, metres squared) from the k nearest neighbours of each point, "
      "regularized to a plane (eigenvalues 1e-3, 1, 1).");

  py::class_<Frame, std::shared_ptr<Frame>> frame(
      m, "Frame",
      "A scan prepared for registration: voxel-downsampled points (the frame's own coordinates, "
      "metres), GICP covariances and a k-d tree. Immutable.");
  init_checked(frame, &make_frame, py::arg("points"), py::arg("voxel_size") = 0.25,
               py::arg("neighbors") = 10, py::arg("min_points") = 29, py::arg("threads") = 1,
               py::arg("name") = "",
               "Downsamples an N x 3 array, estimates covariances and builds the tree. Raises "
               "carat.Error when fewer than min_points points are left.");
  frame
      .def_property_readonly("points", &frame_points,
                             "The downsampled points, N x 3 float32 (a read-only view)")
      .def_property_readonly(
          "covariances", [](const Frame& f) { return covariances_array(f.cloud()); },
          "The points' covariances, N x 3 x 3 float64 (a copy)")
      .def_property_readonly("name", &Frame::name, "The name used in messages")
      .def_property_readonly("constrained_dof", &Frame::constrained_dof,
                             "Directions of the pose (of 6) that the frame's geometry fixes")
      .def_property_readonly("min_eigenvalue_ratio", &Frame::min_eigenvalue_ratio,
                             "Smallest / largest eigenvalue of the frame's registration Hessian")
      .def("__len__", &Frame::size)
      .def("__repr__", [](const Frame& f) {
        return "<carat.Frame '" + f.name() + "' with " + std::to_string(f.size()) + " points>";
      });
}

}  // namespace carat::python
