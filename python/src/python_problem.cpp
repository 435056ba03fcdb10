#include "python_problem.hpp"

#include <cmath>
#include <cstdint>
#include <limits>

#include "arrays.hpp"
#include "carat/base/error.hpp"
#include "carat/residuals/gicp_block.hpp"
#include "carat/residuals/pose_prior_block.hpp"
#include "carat/residuals/relative_pose_block.hpp"
#include "carat/residuals/relative_pose_se2_block.hpp"
#include "carat/residuals/snavely_block.hpp"
#include "carat/solver/evaluate.hpp"
#include "carat/solver/se2.hpp"
#include "carat/solver/se3.hpp"

namespace carat::python {

namespace {

/// A k x k information matrix from `obj` (None: the identity); ValueError naming `what`.
Eigen::MatrixXd information_argument(const py::handle& obj, int k, const std::string& what) {
  if (obj.is_none()) return Eigen::MatrixXd::Identity(k, k);
  const auto array = as_float64(obj, what);
  if (array.ndim() != 2 || array.shape(0) != k || array.shape(1) != k) {
    throw py::value_error(what + ": expected a " + std::to_string(k) + " x " + std::to_string(k) +
                          " information matrix");
  }
  return Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
      array.data(), k, k);
}

/// A 1-D array of variable ids from `obj`; ValueError naming `what`.
py::array_t<std::int64_t> ids_argument(const py::handle& obj, const std::string& what) {
  const py::array array = py::module_::import("numpy").attr("asarray")(obj);
  const char kind = array.dtype().kind();
  if ((kind != 'i' && kind != 'u') || array.ndim() != 1) {
    throw py::value_error(what + ": expected a 1-D array of variable ids (integers)");
  }
  return py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(array);
}

}  // namespace

std::shared_ptr<const LossFunction> loss_argument(const std::string& name, double scale,
                                                  const std::string& what) {
  try {
    return make_loss(parse_loss_kind(name), scale);
  } catch (const Error& e) {
    throw py::value_error(what + ": " + e.what());
  }
}

PythonProblem::Guard::Guard(PythonProblem& p) : problem(p) {
  if (problem.busy_) {
    throw std::runtime_error(
        "carat.Problem: another call into carat is running on this problem (from another "
        "thread); wait for it");
  }
  problem.busy_ = true;
  problem.forget_evaluations();
}

PythonProblem::Guard::~Guard() {
  problem.forget_evaluations();
  problem.busy_ = false;
}

EvaluationCallback PythonProblem::evaluation_hints() const {
  return [this](const EvaluationHint& hint) {
    for (const std::weak_ptr<const NumpyRows>& batch : batches_) {
      if (const std::shared_ptr<const NumpyRows> rows = batch.lock())
        rows->hint_final(!hint.jacobians && hint.likely_final);
    }
  };
}

void PythonProblem::forget_evaluations() {
  for (const std::weak_ptr<const NumpyRows>& batch : batches_) {
    if (const std::shared_ptr<const NumpyRows> rows = batch.lock()) rows->forget();
  }
}

void PythonProblem::check_free() const {
  if (busy_) {
    throw std::runtime_error(
        "carat.Problem: the problem cannot change while a call into carat runs on it");
  }
}

VariableId PythonProblem::id(int variable, const std::string& what) const {
  if (variable < 0 || variable >= problem_.num_variables()) {
    throw py::value_error(what + ": variable " + std::to_string(variable) +
                          " does not exist (the problem has " +
                          std::to_string(problem_.num_variables()) + " variables)");
  }
  return VariableId{variable};
}

VariableKind PythonProblem::kind(VariableId v) const { return kind_of(problem_.manifold(v)); }

py::object PythonProblem::add_euclidean(const py::handle& values) {
  check_free();
  const auto array = as_float64(values, "add_euclidean");
  if ((array.ndim() != 1 && array.ndim() != 2) || array.size() < 1 ||
      array.shape(array.ndim() - 1) < 1) {
    throw py::value_error(
        "add_euclidean: expected a 1-D array of at least one number (or a 2-D array, a "
        "variable per row)");
  }
  const py::ssize_t count = array.ndim() == 2 ? array.shape(0) : 1;
  const py::ssize_t size = array.shape(array.ndim() - 1);
  for (py::ssize_t k = 0; k < array.size(); ++k) {
    if (!std::isfinite(array.data()[k])) {
      throw py::value_error("add_euclidean: value " + std::to_string(k) + " is not finite");
    }
  }
  py::array_t<std::int64_t> out(count);
  for (py::ssize_t k = 0; k < count; ++k) {
    out.mutable_data()[k] =
        problem_.add_euclidean(Eigen::Map<const Eigen::VectorXd>(array.data() + k * size, size))
            .index;
  }
  if (array.ndim() == 1) return py::int_(out.data()[0]);
  return out;
}

int PythonProblem::add_se3(const py::handle& T_world_body) {
  check_free();
  return problem_.add_se3(pose_from_array(T_world_body, "add_se3")).index;
}

int PythonProblem::add_se2(const py::handle& T_world_body) {
  check_free();
  return problem_.add_se2(pose2_from_array(T_world_body, "add_se2")).index;
}

std::vector<VariableId> PythonProblem::ids(const py::handle& variables, const std::string& what,
                                           bool* scalar) const {
  const py::array array = py::module_::import("numpy").attr("asarray")(variables);
  const char type = array.dtype().kind();
  if ((type != 'i' && type != 'u') || array.ndim() > 1) {
    throw py::value_error(what + ": expected a variable id or a 1-D array of them");
  }
  if (scalar) *scalar = array.ndim() == 0;
  const auto values =
      py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(array);
  std::vector<VariableId> out(static_cast<std::size_t>(values.size()));
  for (std::size_t k = 0; k < out.size(); ++k) {
    const std::int64_t raw = values.data()[k];
    out[k] =
        id(raw < 0 || raw > std::numeric_limits<int>::max() ? -1 : static_cast<int>(raw), what);
  }
  return out;
}

void PythonProblem::set_constant(const py::handle& variables, bool constant) {
  check_free();
  for (VariableId v : ids(variables, "set_constant")) problem_.set_constant(v, constant);
}

bool PythonProblem::is_constant(int variable) const {
  return problem_.is_constant(id(variable, "is_constant"));
}

void PythonProblem::set_eliminable(const py::handle& variables, bool eliminable) {
  check_free();
  for (VariableId v : ids(variables, "set_eliminable")) problem_.set_eliminable(v, eliminable);
}

py::array_t<double> PythonProblem::value(const py::handle& variables) const {
  bool scalar = false;
  const std::vector<VariableId> list = ids(variables, "value", &scalar);
  if (scalar) {
    const VariableId v = list.front();
    return value_array(kind(v), problem_.manifold(v).ambient_size(), problem_.value(v).data());
  }
  const VariableKind first = list.empty() ? VariableKind::kEuclidean : kind(list.front());
  const int ambient = list.empty() ? 1 : problem_.manifold(list.front()).ambient_size();
  std::vector<py::ssize_t> shape = value_shape(first, ambient);
  shape.insert(shape.begin(), static_cast<py::ssize_t>(list.size()));
  py::array_t<double> out(shape);
  const auto size = static_cast<std::size_t>(value_size(first, ambient));
  for (std::size_t k = 0; k < list.size(); ++k) {
    if (kind(list[k]) != first || problem_.manifold(list[k]).ambient_size() != ambient) {
      throw py::value_error("value: variable " + std::to_string(list[k].index) + " is " +
                            describe(kind(list[k]), problem_.manifold(list[k]).ambient_size()) +
                            ", not " + describe(first, ambient) + " as the first one");
    }
    write_value(first, ambient, problem_.value(list[k]).data(), out.mutable_data() + k * size);
  }
  return out;
}

void PythonProblem::set_value(int variable, const py::handle& value) {
  check_free();
  const VariableId v = id(variable, "set_value");
  const std::span<double> storage = problem_.mutable_value(v);
  switch (kind(v)) {
    case VariableKind::kSE3:
      se3::to_storage(pose_from_array(value, "set_value"), storage.data());
      return;
    case VariableKind::kSE2:
      se2::to_storage(pose2_from_array(value, "set_value"), storage.data());
      return;
    case VariableKind::kEuclidean:
      break;
  }
  const auto array = as_float64(value, "set_value");
  if (array.ndim() != 1 || static_cast<std::size_t>(array.shape(0)) != storage.size()) {
    throw py::value_error("set_value: variable " + std::to_string(variable) + " is euclidean(" +
                          std::to_string(storage.size()) + "); expected " +
                          std::to_string(storage.size()) + " numbers");
  }
  for (std::size_t k = 0; k < storage.size(); ++k) {
    if (!std::isfinite(array.data()[k])) {
      throw py::value_error("set_value: value " + std::to_string(k) + " is not finite");
    }
  }
  std::copy_n(array.data(), storage.size(), storage.data());
}

int PythonProblem::add_relative_pose(int i, int j, const py::handle& T_i_j,
                                     const py::handle& information, const std::string& loss,
                                     double loss_scale) {
  check_free();
  const VariableId vi = id(i, "add_relative_pose");
  const VariableId vj = id(j, "add_relative_pose");
  for (VariableId v : {vi, vj}) {
    if (kind(v) != VariableKind::kSE3) {
      throw py::value_error("add_relative_pose: variable " + std::to_string(v.index) + " is " +
                            problem_.manifold(v).name() + "; expected an SE(3) variable");
    }
  }
  const se3::Matrix6d info = information_argument(information, 6, "add_relative_pose information");
  auto block =
      std::make_shared<RelativePoseBlock>(pose_from_array(T_i_j, "add_relative_pose T_i_j"), info);
  return problem_
      .add_residual_block(block, {vi, vj}, loss_argument(loss, loss_scale, "add_relative_pose"))
      .index;
}

int PythonProblem::add_relative_pose_se2(int i, int j, const py::handle& T_i_j,
                                         const py::handle& information, const std::string& loss,
                                         double loss_scale) {
  check_free();
  const VariableId vi = id(i, "add_relative_pose_se2");
  const VariableId vj = id(j, "add_relative_pose_se2");
  for (VariableId v : {vi, vj}) {
    if (kind(v) != VariableKind::kSE2) {
      throw py::value_error("add_relative_pose_se2: variable " + std::to_string(v.index) + " is " +
                            problem_.manifold(v).name() + "; expected an SE(2) variable");
    }
  }
  const Eigen::Matrix3d info =
      information_argument(information, 3, "add_relative_pose_se2 information");
  auto block = std::make_shared<RelativePoseSE2Block>(
      pose2_from_array(T_i_j, "add_relative_pose_se2 T_i_j"), info);
  return problem_
      .add_residual_block(block, {vi, vj}, loss_argument(loss, loss_scale, "add_relative_pose_se2"))
      .index;
}

int PythonProblem::add_pose_prior(int variable, const py::handle& T_world_prior,
                                  const py::handle& information, const std::string& loss,
                                  double loss_scale) {
  check_free();
  const VariableId v = id(variable, "add_pose_prior");
  if (kind(v) != VariableKind::kSE3) {
    throw py::value_error("add_pose_prior: variable " + std::to_string(variable) + " is " +
                          problem_.manifold(v).name() + "; expected an SE(3) variable");
  }
  const se3::Matrix6d info = information_argument(information, 6, "add_pose_prior information");
  auto block = std::make_shared<PosePriorBlock>(
      pose_from_array(T_world_prior, "add_pose_prior T_world_prior"), info);
  return problem_.add_residual_block(block, {v}, loss_argument(loss, loss_scale, "add_pose_prior"))
      .index;
}

int PythonProblem::add_gicp(int i, int j, const py::handle& target_means,
                            const py::handle& target_covariances, const py::handle& source_means,
                            const py::handle& source_covariances, const py::handle& T_target_source,
                            const std::string& loss, double loss_scale) {
  check_free();
  const VariableId vi = id(i, "add_gicp");
  const VariableId vj = id(j, "add_gicp");
  for (VariableId v : {vi, vj}) {
    if (kind(v) != VariableKind::kSE3) {
      throw py::value_error("add_gicp: variable " + std::to_string(v.index) + " is " +
                            problem_.manifold(v).name() + "; expected an SE(3) variable");
    }
  }
  const auto mu_target = as_float64(target_means, "add_gicp target_means");
  const auto C_target = as_float64(target_covariances, "add_gicp target_covariances");
  const auto mu_source = as_float64(source_means, "add_gicp source_means");
  const auto C_source = as_float64(source_covariances, "add_gicp source_covariances");
  const py::ssize_t n = mu_target.ndim() == 2 ? mu_target.shape(0) : -1;
  const auto means_ok = [n](const py::array_t<double>& a) {
    return a.ndim() == 2 && a.shape(0) == n && a.shape(1) == 3;
  };
  const auto covariances_ok = [n](const py::array_t<double>& a) {
    return a.ndim() == 3 && a.shape(0) == n && a.shape(1) == 3 && a.shape(2) == 3;
  };
  if (n < 1 || !means_ok(mu_target) || !means_ok(mu_source) || !covariances_ok(C_target) ||
      !covariances_ok(C_source)) {
    throw py::value_error(
        "add_gicp: expected target_means and source_means of shape (N, 3) and target_covariances "
        "and source_covariances of shape (N, 3, 3), N >= 1");
  }
  std::vector<GicpCorrespondence> correspondences(static_cast<std::size_t>(n));
  using Row3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;
  for (py::ssize_t k = 0; k < n; ++k) {
    GicpCorrespondence& c = correspondences[static_cast<std::size_t>(k)];
    c.mean_target = Eigen::Map<const Eigen::Vector3d>(mu_target.data() + 3 * k);
    c.mean_source = Eigen::Map<const Eigen::Vector3d>(mu_source.data() + 3 * k);
    c.covariance_target = Eigen::Map<const Row3>(C_target.data() + 9 * k);
    c.covariance_source = Eigen::Map<const Row3>(C_source.data() + 9 * k);
  }
  const Eigen::Isometry3d T = T_target_source.is_none()
                                  ? se3::from_storage(problem_.value(vi).data()).inverse() *
                                        se3::from_storage(problem_.value(vj).data())
                                  : pose_from_array(T_target_source, "add_gicp T_target_source");
  std::shared_ptr<GicpBlock> block;
  try {
    block = std::make_shared<GicpBlock>(correspondences, T);
  } catch (const Error& e) {
    throw py::value_error(std::string("add_gicp: ") + e.what());
  }
  return problem_.add_residual_block(block, {vi, vj}, loss_argument(loss, loss_scale, "add_gicp"))
      .index;
}

py::array_t<int> PythonProblem::add_bal_observations(const py::handle& cameras,
                                                     const py::handle& points,
                                                     const py::handle& observed,
                                                     const std::string& loss, double loss_scale) {
  check_free();
  const auto camera_ids = ids_argument(cameras, "add_bal_observations cameras");
  const auto point_ids = ids_argument(points, "add_bal_observations points");
  const auto xy = as_float64(observed, "add_bal_observations observed");
  const py::ssize_t n = camera_ids.shape(0);
  if (point_ids.shape(0) != n || xy.ndim() != 2 || xy.shape(0) != n || xy.shape(1) != 2) {
    throw py::value_error(
        "add_bal_observations: expected cameras and points of N variable ids and observed of "
        "shape (N, 2)");
  }
  const auto shared_loss = loss_argument(loss, loss_scale, "add_bal_observations");
  const auto checked = [&](std::int64_t variable, int size, const char* what) {
    if (variable < 0 || variable >= problem_.num_variables()) {
      throw py::value_error(std::string("add_bal_observations: ") + what + " " +
                            std::to_string(variable) + " does not exist");
    }
    const VariableId v{static_cast<int>(variable)};
    if (kind(v) != VariableKind::kEuclidean || problem_.manifold(v).ambient_size() != size) {
      throw py::value_error(std::string("add_bal_observations: ") + what + " " +
                            std::to_string(variable) + " is not euclidean(" + std::to_string(size) +
                            ")");
    }
    return v;
  };
  py::array_t<int> ids(n);
  for (py::ssize_t k = 0; k < n; ++k) {
    const VariableId camera = checked(camera_ids.data()[k], 9, "camera");
    const VariableId point = checked(point_ids.data()[k], 3, "point");
    auto block = std::make_shared<SnavelyReprojectionBlock>(xy.data()[2 * k], xy.data()[2 * k + 1]);
    ids.mutable_data()[k] = problem_.add_residual_block(block, {camera, point}, shared_loss).index;
  }
  return ids;
}

double PythonProblem::cost(int threads) {
  threads_argument(threads);
  return run([&](Problem& problem, InterruptCheck&) { return evaluate_cost(problem, threads); });
}

py::array_t<double> PythonProblem::gradient(int threads) {
  threads_argument(threads);
  const Eigen::VectorXd g = run([&](Problem& problem, InterruptCheck&) {
    return evaluate_problem(problem, threads).gradient;
  });
  py::array_t<double> out(static_cast<py::ssize_t>(g.size()));
  std::copy_n(g.data(), g.size(), out.mutable_data());
  return out;
}

}  // namespace carat::python
