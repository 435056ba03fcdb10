// Scan matching from Python: carat.align, and a pair's GICP factor with its lossless rows.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numeric>
#include <string>
#include <vector>

#include "arrays.hpp"
#include "bindings.hpp"
#include "carat/base/error.hpp"
#include "carat/registration/align.hpp"
#include "carat/registration/correspondences.hpp"
#include "carat/registration/frame.hpp"
#include "carat/residuals/gicp_block.hpp"
#include "carat/residuals/lossless_block.hpp"
#include "carat/solver/se3.hpp"
#include "integer_arguments.hpp"
#include "interrupt.hpp"

namespace carat::python {

namespace {

/// A number as printf's %g writes it.
std::string py_number(double value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%g", value);
  return text;
}

/// A frame argument: a carat.Frame as it is, or an array of points preprocessed here.
std::shared_ptr<const Frame> frame_argument(const py::handle& obj, const std::string& what,
                                            double voxel_size, int neighbors, int threads) {
  if (py::isinstance<Frame>(obj)) return obj.cast<std::shared_ptr<Frame>>();
  const PointCloud raw = cloud_from_array(obj, what);
  PreprocessOptions options;
  options.voxel_size = voxel_size;
  options.covariance_neighbors = neighbors_argument(neighbors);
  options.num_threads = threads_argument(threads);
  return run_released([&](InterruptCheck&) { return preprocess_frame(raw, options, what); });
}

/// Residuals (N) and reduced Jacobian rows (N x 6, right tangent of T_target_source) of a binary
/// registration block at a relative pose.
py::tuple evaluate_block(const ResidualBlock& block, const Eigen::Isometry3d& T_target_source) {
  std::array<double, 7> target{};
  std::array<double, 7> source{};
  se3::to_storage(Eigen::Isometry3d::Identity(), target.data());
  se3::to_storage(T_target_source, source.data());
  const std::array<const double*, 2> params{target.data(), source.data()};
  const int n = block.num_rows();
  std::vector<int> rows(static_cast<std::size_t>(n));
  std::iota(rows.begin(), rows.end(), 0);
  py::array_t<double> residuals(n);
  py::array_t<double> jacobian({py::ssize_t{n}, py::ssize_t{block.reduced_dim()}});
  {
    py::gil_scoped_release release;
    block.evaluate_rows(params, rows, residuals.mutable_data(), jacobian.mutable_data());
  }
  return py::make_tuple(residuals, jacobian);
}

double block_cost(const ResidualBlock& block, const Eigen::Isometry3d& T_target_source) {
  std::array<double, 7> target{};
  std::array<double, 7> source{};
  se3::to_storage(Eigen::Isometry3d::Identity(), target.data());
  se3::to_storage(T_target_source, source.data());
  const std::array<const double*, 2> params{target.data(), source.data()};
  py::gil_scoped_release release;
  return block.squared_norm(params);
}

/// The GICP factor of a frame pair: its correspondences fixed at a relative pose.
struct GicpFactor {
  std::shared_ptr<const GicpBlock> block;
  Eigen::Isometry3d T_target_source;
};

/// The lossless rows of a factor.
struct LosslessFactor {
  std::shared_ptr<const LosslessRegistrationBlock> block;
};

GicpFactor make_gicp_factor(const std::shared_ptr<Frame>& target,
                            const std::shared_ptr<Frame>& source, const py::handle& T,
                            double max_correspondence_distance) {
  const Eigen::Isometry3d T_target_source = pose_from_array(T, "T_target_source");
  if (!(std::isfinite(max_correspondence_distance) && max_correspondence_distance > 0.0)) {
    throw py::value_error("max_correspondence_distance: must be finite and > 0 (metres)");
  }
  return run_released([&](InterruptCheck&) {
    const auto correspondences =
        find_correspondences(target->cloud(), target->tree(), source->cloud(), T_target_source,
                             max_correspondence_distance);
    if (correspondences.empty()) {
      throw Error("GicpFactor: no source point has a target point within " +
                  py_number(max_correspondence_distance) + " m at the given pose");
    }
    return GicpFactor{std::make_shared<const GicpBlock>(correspondences, T_target_source),
                      T_target_source};
  });
}

AlignResult align_frames(const py::handle& target_in, const py::handle& source_in,
                         const py::object& T_init, const std::string& method,
                         double max_correspondence_distance, int max_iterations, double voxel_size,
                         int neighbors, int threads) {
  AlignSettings settings;
  settings.method = parse_registration_method(method);
  settings.max_correspondence_distance = max_correspondence_distance;
  settings.max_iterations = max_iterations;
  settings.num_threads = threads_argument(threads);
  const Eigen::Isometry3d T0 =
      T_init.is_none() ? Eigen::Isometry3d::Identity() : pose_from_array(T_init, "T_init");
  const auto target = frame_argument(target_in, "target", voxel_size, neighbors, threads);
  const auto source = frame_argument(source_in, "source", voxel_size, neighbors, threads);
  return run_released([&](InterruptCheck&) {
    return align(target->cloud(), target->tree(), source->cloud(), T0, settings);
  });
}

}  // namespace

void bind_registration(py::module_& m) {
  py::class_<AlignResult>(m, "AlignResult", "What carat.align found.")
      .def_property_readonly(
          "T_target_source",
          [](const AlignResult& r) { return array_from_pose(r.T_target_source); },
          "4 x 4 transform mapping source points into the target frame")
      .def_property_readonly(
          "H", [](const AlignResult& r) { return Eigen::Matrix<double, 6, 6>(r.H); },
          "J^T J of the rows at the result (6 x 6, right tangent [w, v] of T_target_source)")
      .def_readonly("error", &AlignResult::error, "Sum of squared residuals at the result")
      .def_readonly("iterations", &AlignResult::iterations, "Outer iterations run")
      .def_readonly("num_correspondences", &AlignResult::num_correspondences,
                    "Pairs used in the last iteration")
      .def_readonly("converged", &AlignResult::converged, "The last step was below tolerance")
      .def_readonly("constrained_dof", &AlignResult::constrained_dof,
                    "Directions (of 6) the geometry constrains")
      .def_readonly("min_eigenvalue_ratio", &AlignResult::min_eigenvalue_ratio,
                    "Smallest / largest eigenvalue of the scaled H")
      .def_readonly("search_s", &AlignResult::search_s, "Seconds finding correspondences")
      .def_readonly("optimize_s", &AlignResult::optimize_s, "Seconds building blocks and solving")
      .def("__repr__", [](const AlignResult& r) {
        return "<carat.AlignResult converged=" + std::string(r.converged ? "True" : "False") +
               " iterations=" + std::to_string(r.iterations) +
               " correspondences=" + std::to_string(r.num_correspondences) + ">";
      });

  def_checked(m, "align", &align_frames, py::arg("target"), py::arg("source"),
              py::arg("T_init") = py::none(), py::arg("method") = "gicp",
              py::arg("max_correspondence_distance") = 1.0, py::arg("max_iterations") = 30,
              py::arg("voxel_size") = 0.25, py::arg("neighbors") = 10, py::arg("threads") = 1,
              R"(Aligns source onto target (GICP, or 'point-to-plane' / 'point-to-point' ICP).

target, source: carat.Frame, or N x 3 arrays of points (metres), then downsampled with
voxel_size and given covariances from `neighbors` nearest points.
T_init: 4 x 4 initial T_target_source (None: identity).
Returns a carat.AlignResult (T_target_source, H, error, iterations, converged, ...).)");

  py::class_<LosslessFactor>(
      m, "LosslessFactor",
      "At most 13 rows whose cost, gradient and Gauss-Newton Hessian equal a registration "
      "factor's at every relative pose.")
      .def_property_readonly(
          "num_rows", [](const LosslessFactor& f) { return f.block->num_rows(); },
          "Rows (the numerical rank of the Gram matrix, at most 13)")
      .def_property_readonly(
          "original_rows", [](const LosslessFactor& f) { return f.block->original_rows(); },
          "Rows of the factor it replaces")
      .def(
          "evaluate",
          [](const LosslessFactor& f, const py::handle& T) {
            return evaluate_block(*f.block, pose_from_array(T, "T_target_source"));
          },
          py::arg("T_target_source"), "(residuals, J (rows x 6)) at a relative pose")
      .def(
          "cost",
          [](const LosslessFactor& f, const py::handle& T) {
            return block_cost(*f.block, pose_from_array(T, "T_target_source"));
          },
          py::arg("T_target_source"), "Sum of squared residuals at a relative pose");

  py::class_<GicpFactor>(
      m, "GicpFactor",
      "The GICP residual block of a frame pair, correspondences fixed at a relative pose: three "
      "rows per correspondence, Jacobians with respect to the right tangent [w, v] of "
      "T_target_source.")
      .def(py::init(&make_gicp_factor), py::arg("target").none(false),
           py::arg("source").none(false), py::arg("T_target_source"),
           py::arg("max_correspondence_distance") = 1.0,
           "Nearest-neighbour correspondences of source in target under T_target_source (up to "
           "max_correspondence_distance metres) with fused covariances.")
      .def_property_readonly(
          "num_rows", [](const GicpFactor& f) { return f.block->num_rows(); }, "Rows N")
      .def_property_readonly(
          "num_correspondences", [](const GicpFactor& f) { return f.block->num_correspondences(); },
          "Correspondences held")
      .def(
          "evaluate",
          [](const GicpFactor& f, const py::handle& T) {
            return evaluate_block(*f.block, pose_from_array(T, "T_target_source"));
          },
          py::arg("T_target_source"),
          "(residuals (N), J (N x 6)) at a relative pose: the rows carat.coreset compresses")
      .def(
          "cost",
          [](const GicpFactor& f, const py::handle& T) {
            return block_cost(*f.block, pose_from_array(T, "T_target_source"));
          },
          py::arg("T_target_source"), "Sum of squared residuals at a relative pose")
      .def(
          "lossless",
          [](const GicpFactor& f, const py::object& T_reference) {
            const Eigen::Isometry3d T = T_reference.is_none()
                                            ? f.T_target_source
                                            : pose_from_array(T_reference, "T_reference");
            return LosslessFactor{make_lossless_block(*f.block, T)};
          },
          py::arg("T_reference") = py::none(),
          "At most 13 rows with the same cost as the factor at every relative pose (the "
          "factored Gram matrix; T_reference only conditions the numbers; None: the pose the "
          "factor was built at)");
}

}  // namespace carat::python
