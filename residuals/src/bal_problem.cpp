#include "carat/residuals/bal_problem.hpp"

#include <array>
#include <cmath>
#include <span>
#include <string>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/residuals/bal_camera_manifold.hpp"
#include "carat/residuals/snavely_block.hpp"
#include "carat/residuals/snavely_camera.hpp"
#include "carat/solver/lie_functions.hpp"
#include "carat/solver/manifold.hpp"

namespace carat {

void check_bal_problem(const BalProblem& problem, const char* name) {
  const std::string who(name);
  if (problem.cameras.empty() || problem.points.empty() || problem.observations.empty()) {
    throw Error(who + ": " + std::to_string(problem.cameras.size()) + " cameras, " +
                std::to_string(problem.points.size()) + " points and " +
                std::to_string(problem.observations.size()) +
                " observations (a problem needs at least one of each)");
  }
  std::vector<char> camera_used(problem.cameras.size(), 0);
  std::vector<char> point_used(problem.points.size(), 0);
  for (std::size_t i = 0; i < problem.cameras.size(); ++i) {
    if (!problem.cameras[i].allFinite())
      throw Error(who + ": camera " + std::to_string(i) + " has a non-finite parameter");
  }
  for (std::size_t i = 0; i < problem.points.size(); ++i) {
    if (!problem.points[i].allFinite())
      throw Error(who + ": point " + std::to_string(i) + " has a non-finite coordinate");
  }
  for (std::size_t k = 0; k < problem.observations.size(); ++k) {
    const BalObservation& o = problem.observations[k];
    if (o.camera < 0 || static_cast<std::size_t>(o.camera) >= problem.cameras.size()) {
      throw Error(who + ": observation " + std::to_string(k) + " names camera " +
                  std::to_string(o.camera) + " of " + std::to_string(problem.cameras.size()));
    }
    if (o.point < 0 || static_cast<std::size_t>(o.point) >= problem.points.size()) {
      throw Error(who + ": observation " + std::to_string(k) + " names point " +
                  std::to_string(o.point) + " of " + std::to_string(problem.points.size()));
    }
    if (!std::isfinite(o.x) || !std::isfinite(o.y))
      throw Error(who + ": observation " + std::to_string(k) + " is not finite");
    camera_used[static_cast<std::size_t>(o.camera)] = 1;
    point_used[static_cast<std::size_t>(o.point)] = 1;
  }
  for (std::size_t i = 0; i < camera_used.size(); ++i) {
    if (!camera_used[i]) throw Error(who + ": camera " + std::to_string(i) + " observes no point");
  }
  for (std::size_t i = 0; i < point_used.size(); ++i) {
    if (!point_used[i])
      throw Error(who + ": point " + std::to_string(i) + " is observed by no camera");
  }
}

BalVariables add_bal_problem(const BalProblem& bal, Problem* problem,
                             std::shared_ptr<const LossFunction> loss,
                             BalCameraTangent camera_tangent) {
  if (problem == nullptr) throw Error("add_bal_problem: no problem given");
  check_bal_problem(bal);
  BalVariables out;
  out.cameras.reserve(bal.cameras.size());
  out.points.reserve(bal.points.size());
  const auto camera_manifold = camera_tangent == BalCameraTangent::kAboutCentre
                                   ? bal_camera_manifold()
                                   : euclidean_manifold(kBalCameraSize);
  const auto point_manifold = euclidean_manifold(3);
  for (const BalCamera& camera : bal.cameras) {
    out.cameras.push_back(
        problem->add_variable(camera_manifold, std::span<const double>(camera.data(), 9)));
  }
  for (const Eigen::Vector3d& point : bal.points) {
    const VariableId id =
        problem->add_variable(point_manifold, std::span<const double>(point.data(), 3));
    problem->set_eliminable(id);
    out.points.push_back(id);
  }
  for (const BalObservation& o : bal.observations) {
    problem->add_residual_block(
        std::make_shared<SnavelyReprojectionBlock>(o.x, o.y, camera_tangent),
        {out.cameras[static_cast<std::size_t>(o.camera)],
         out.points[static_cast<std::size_t>(o.point)]},
        loss);
  }
  return out;
}

void update_bal_problem(const Problem& problem, const BalVariables& variables, BalProblem* bal) {
  if (bal == nullptr) throw Error("update_bal_problem: no BAL problem given");
  if (variables.cameras.size() != bal->cameras.size() ||
      variables.points.size() != bal->points.size()) {
    throw Error("update_bal_problem: " + std::to_string(variables.cameras.size()) + " camera and " +
                std::to_string(variables.points.size()) + " point variables for a BAL problem of " +
                std::to_string(bal->cameras.size()) + " cameras and " +
                std::to_string(bal->points.size()) + " points");
  }
  for (std::size_t i = 0; i < bal->cameras.size(); ++i) {
    const auto value = problem.value(variables.cameras[i]);
    for (int k = 0; k < kBalCameraSize; ++k)
      bal->cameras[i][k] = value[static_cast<std::size_t>(k)];
  }
  for (std::size_t i = 0; i < bal->points.size(); ++i) {
    const auto value = problem.value(variables.points[i]);
    for (int k = 0; k < 3; ++k) bal->points[i][k] = value[static_cast<std::size_t>(k)];
  }
}

double bal_cost(const BalProblem& bal) {
  check_bal_problem(bal, "bal_cost");
  double sum = 0.0;
  for (const BalObservation& o : bal.observations) {
    double image[2];
    snavely_project(bal.cameras[static_cast<std::size_t>(o.camera)].data(),
                    bal.points[static_cast<std::size_t>(o.point)].data(), image);
    const double dx = image[0] - o.x, dy = image[1] - o.y;
    sum += dx * dx + dy * dy;
  }
  return 0.5 * sum;
}

std::size_t count_points_behind_cameras(const BalProblem& bal) {
  check_bal_problem(bal, "count_points_behind_cameras");
  // in_front_of_camera()'s arithmetic, each camera's Rodrigues coefficients computed once.
  std::vector<std::array<double, 2>> coefficients(bal.cameras.size());
  for (std::size_t c = 0; c < bal.cameras.size(); ++c) {
    lie::angle_axis_coefficients(bal.cameras[c].data(), &coefficients[c][0], &coefficients[c][1]);
  }
  std::size_t count = 0;
  for (const BalObservation& o : bal.observations) {
    const auto c = static_cast<std::size_t>(o.camera);
    const double* camera = bal.cameras[c].data();
    double P[3];
    lie::angle_axis_rotate(camera, coefficients[c][0], coefficients[c][1],
                           bal.points[static_cast<std::size_t>(o.point)].data(), P);
    if (!(P[2] + camera[5] < 0.0)) ++count;
  }
  return count;
}

}  // namespace carat
