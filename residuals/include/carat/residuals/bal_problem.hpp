#pragma once

/// A bundle-adjustment problem in the terms of the BAL data sets: cameras (9 parameters each, see
/// snavely_camera.hpp), world points (scene units) and observations (pixels), and how it becomes
/// a carat Problem of SnavelyReprojectionBlocks.

#include <Eigen/Core>
#include <cstddef>
#include <memory>
#include <vector>

#include "carat/residuals/snavely_camera.hpp"
#include "carat/solver/loss_function.hpp"
#include "carat/solver/problem.hpp"
#include "carat/solver/variable_id.hpp"

namespace carat {

/// One camera's parameters [w (3, radians), t (3), f (pixels), k1, k2].
using BalCamera = Eigen::Matrix<double, 9, 1>;

/// One image measurement of one point by one camera.
struct BalObservation {
  int camera = 0;  ///< index into BalProblem::cameras
  int point = 0;   ///< index into BalProblem::points
  double x = 0.0;  ///< observed image x, pixels (relative to the image centre)
  double y = 0.0;  ///< observed image y, pixels (relative to the image centre)
};

/// Cameras, world points and observations of a bundle-adjustment problem.
struct BalProblem {
  std::vector<BalCamera> cameras;            ///< camera parameters
  std::vector<Eigen::Vector3d> points;       ///< world points, scene units
  std::vector<BalObservation> observations;  ///< measurements, in file order
};

/// Throws carat::Error ("`name`: ...") unless the problem has cameras, points and observations,
/// every observation names an existing camera and point, every camera observes a point, every point
/// is observed and every value is finite.
void check_bal_problem(const BalProblem& problem, const char* name = "BAL problem");

/// The variables add_bal_problem() created, by camera and point index.
struct BalVariables {
  std::vector<VariableId> cameras;  ///< one 9-parameter variable per camera (see add_bal_problem)
  std::vector<VariableId> points;   ///< one Euclidean(3) variable per point, marked eliminable
};

/// Adds one variable per camera and per point (points Euclidean and marked eliminable, for the
/// Schur complement) and one SnavelyReprojectionBlock per observation, with `loss` (null: plain
/// least squares), to `problem`. Cameras step in `camera_tangent`: by default about their centre
/// (bal_camera_manifold(); Gauss-Newton needs fewer iterations where the scene lies far from
/// the world origin), or kParameters for Euclidean(9) variables. The cost function and its
/// optimum are the same either way. Throws carat::Error if `bal` fails check_bal_problem().
BalVariables add_bal_problem(const BalProblem& bal, Problem* problem,
                             std::shared_ptr<const LossFunction> loss = nullptr,
                             BalCameraTangent camera_tangent = BalCameraTangent::kAboutCentre);

/// Copies the current camera and point values of `problem` back into `bal` (observations are left
/// as they are). Throws carat::Error if the sizes of `variables` and `bal` differ.
void update_bal_problem(const Problem& problem, const BalVariables& variables, BalProblem* bal);

/// The cost 1/2 sum over observations of |image - observed|^2 (pixels^2), evaluated directly
/// (no Problem); the same as Problem::evaluate_cost() of add_bal_problem() without a loss.
double bal_cost(const BalProblem& bal);

/// Number of observations whose point is not in front of its camera (P_z >= 0 in the camera
/// frame, see snavely_camera.hpp). Such observations still have a residual (the model projects
/// them through the centre; P_z = 0 gives a non-finite one): readers accept them, as real data
/// holds a few, and callers decide, e.g. report the count or drop them.
std::size_t count_points_behind_cameras(const BalProblem& bal);

}  // namespace carat
