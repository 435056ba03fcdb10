#pragma once

/// The variables of a Python-built problem as numpy sees them: a Euclidean variable as a 1-D
/// array, an SE(3) pose T_world_body as a 4 x 4 matrix, an SE(2) pose as a 3 x 3 homogeneous
/// matrix; and the central-difference steps taken through each manifold.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "carat/solver/manifold.hpp"

namespace carat::python {

namespace py = pybind11;

/// The manifolds the Python module creates variables on.
enum class VariableKind {
  kEuclidean,  ///< R^n: stored and shown as n numbers
  kSE3,        ///< stored [qx, qy, qz, qw, tx, ty, tz], shown 4 x 4; tangent [omega, v]
  kSE2,        ///< stored [x, y, theta], shown 3 x 3; tangent [omega, vx, vy]
};

/// "euclidean(n)", "se3" or "se2".
std::string describe(VariableKind kind, int ambient);

/// The kind of a carat manifold (by its name); throws carat::Error for another one.
VariableKind kind_of(const Manifold& manifold);

/// Shape of one value in numpy: (n,), (4, 4) or (3, 3).
std::vector<py::ssize_t> value_shape(VariableKind kind, int ambient);

/// Doubles of one value in numpy (the product of value_shape()).
int value_size(VariableKind kind, int ambient);

/// Writes the numpy form of the stored value `storage` (row-major, value_size() doubles).
void write_value(VariableKind kind, int ambient, const double* storage, double* out);

/// One value as a new numpy array.
py::array_t<double> value_array(VariableKind kind, int ambient, const double* storage);

/// The central-difference step along tangent direction `d` at `storage`: 6e-6 (about the cube
/// root of the machine epsilon) times max(1, |x_d|) for a Euclidean coordinate, times 1 for a
/// rotation and max(1, |t|) for a translation direction of a pose.
double difference_step(VariableKind kind, int ambient, const double* storage, int d);

/// A 2-D rigid transform from a 3 x 3 homogeneous matrix (finite, last row (0, 0, 1), rotation
/// orthonormal to 1e-6 with determinant +1) or from [x, y, theta] (metres, radians); ValueError
/// naming `what` otherwise.
Eigen::Isometry2d pose2_from_array(const py::handle& obj, const std::string& what);

}  // namespace carat::python
