#include "variable_values.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "arrays.hpp"
#include "carat/base/error.hpp"
#include "carat/solver/se2.hpp"
#include "carat/solver/se3.hpp"

namespace carat::python {

namespace {

constexpr double kRelativeStep = 6e-6;

}  // namespace

std::string describe(VariableKind kind, int ambient) {
  switch (kind) {
    case VariableKind::kSE3:
      return "se3";
    case VariableKind::kSE2:
      return "se2";
    case VariableKind::kEuclidean:
      break;
  }
  return "euclidean(" + std::to_string(ambient) + ")";
}

VariableKind kind_of(const Manifold& manifold) {
  const std::string name = manifold.name();
  if (name == "euclidean") return VariableKind::kEuclidean;
  if (name == "se3") return VariableKind::kSE3;
  if (name == "se2") return VariableKind::kSE2;
  throw Error("a variable on the manifold '" + name + "' has no numpy form");
}

std::vector<py::ssize_t> value_shape(VariableKind kind, int ambient) {
  switch (kind) {
    case VariableKind::kSE3:
      return {4, 4};
    case VariableKind::kSE2:
      return {3, 3};
    case VariableKind::kEuclidean:
      break;
  }
  return {ambient};
}

int value_size(VariableKind kind, int ambient) {
  switch (kind) {
    case VariableKind::kSE3:
      return 16;
    case VariableKind::kSE2:
      return 9;
    case VariableKind::kEuclidean:
      break;
  }
  return ambient;
}

void write_value(VariableKind kind, int ambient, const double* storage, double* out) {
  switch (kind) {
    case VariableKind::kSE3: {
      Eigen::Map<Eigen::Matrix<double, 4, 4, Eigen::RowMajor>> matrix(out);
      matrix = se3::from_storage(storage).matrix();
      return;
    }
    case VariableKind::kSE2: {
      Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> matrix(out);
      matrix = se2::from_storage(storage).matrix();
      return;
    }
    case VariableKind::kEuclidean:
      break;
  }
  std::copy_n(storage, ambient, out);
}

py::array_t<double> value_array(VariableKind kind, int ambient, const double* storage) {
  py::array_t<double> out(value_shape(kind, ambient));
  write_value(kind, ambient, storage, out.mutable_data());
  return out;
}

double difference_step(VariableKind kind, int ambient, const double* storage, int d) {
  switch (kind) {
    case VariableKind::kSE3:
      return d < 3 ? kRelativeStep
                   : kRelativeStep * std::max(1.0, Eigen::Map<const Eigen::Vector3d>(storage + 4)
                                                       .lpNorm<Eigen::Infinity>());
    case VariableKind::kSE2:
      return d == 0 ? kRelativeStep
                    : kRelativeStep * std::max({1.0, std::abs(storage[0]), std::abs(storage[1])});
    case VariableKind::kEuclidean:
      break;
  }
  (void)ambient;
  return kRelativeStep * std::max(1.0, std::abs(storage[d]));
}

Eigen::Isometry2d pose2_from_array(const py::handle& obj, const std::string& what) {
  const auto array = as_float64(obj, what);
  const double* m = array.data();
  if (array.ndim() == 1 && array.shape(0) == 3) {
    if (!std::isfinite(m[0]) || !std::isfinite(m[1]) || !std::isfinite(m[2])) {
      throw py::value_error(what + ": the pose is not finite");
    }
    return se2::make(m[0], m[1], m[2]);
  }
  if (array.ndim() != 2 || array.shape(0) != 3 || array.shape(1) != 3) {
    throw py::value_error(what + ": expected a 3 x 3 homogeneous matrix or [x, y, theta]");
  }
  for (int k = 0; k < 9; ++k) {
    if (!std::isfinite(m[k])) throw py::value_error(what + ": the pose is not finite");
  }
  const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> M(m);
  if ((M.row(2) - Eigen::RowVector3d(0.0, 0.0, 1.0)).cwiseAbs().maxCoeff() > 1e-9) {
    throw py::value_error(what + ": the last row of a 3 x 3 pose must be (0, 0, 1)");
  }
  const Eigen::Matrix2d R = M.topLeftCorner<2, 2>();
  if ((R.transpose() * R - Eigen::Matrix2d::Identity()).norm() > 1e-6 || R.determinant() <= 0.0) {
    throw py::value_error(what +
                          ": the rotation block is not a rotation (orthonormal to 1e-6, "
                          "determinant +1)");
  }
  return se2::make(M(0, 2), M(1, 2), std::atan2(R(1, 0), R(0, 0)));
}

}  // namespace carat::python
