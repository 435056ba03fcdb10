#pragma once

/// The camera model of the BAL data sets ("Bundle Adjustment in the Large", Agarwal et al.): nine
/// parameters [w (3), t (3), f, k1, k2] with w the angle-axis rotation (radians) taking world
/// points into the camera frame, t the translation (scene units), f the focal length (pixels) and
/// k1, k2 radial distortion of the normalized image point. A world point X (scene units) maps to
///   P = R(w) X + t,  p = -(P_x, P_y) / P_z,  d = 1 + k1 |p|^2 + k2 |p|^4,  image = f d p (pixels).
/// The camera looks down its -z axis: a point is in front of it when P_z < 0.

#include <cmath>

#include "carat/solver/lie_functions.hpp"

namespace carat {

/// Number of parameters of one BAL camera.
inline constexpr int kBalCameraSize = 9;

/// The tangent a BAL camera variable steps in: kParameters adds steps to the nine numbers
/// (euclidean(9)); kAboutCentre steps the rotation about the camera centre and the centre itself
/// (bal_camera_manifold(), bal_camera_manifold.hpp). A block's camera Jacobian is in its
/// variable's tangent, so the two must match.
enum class BalCameraTangent {
  kParameters,   ///< [w, t, f, k1, k2]: steps added to the nine numbers
  kAboutCentre,  ///< [dw, dc, df, dk1, dk2]: w + dw with the centre held, the centre + dc
};

/// The point `camera` (9 parameters, see above) takes to the camera frame: P = R(w) X + t.
template <typename T>
void snavely_camera_point(const T* camera, const T* point, T* P) {
  lie::angle_axis_rotate(camera, point, P);  // Taylor series below 1e-3 rad
  P[0] += camera[3];
  P[1] += camera[4];
  P[2] += camera[5];
}

/// Projects the world point `point` (3) with `camera` (9) to `image` (2, pixels). A point with
/// P_z = 0 gives a non-finite image; one behind the camera (P_z > 0) is projected all the same.
template <typename T>
void snavely_project(const T* camera, const T* point, T* image) {
  T P[3];
  snavely_camera_point(camera, point, P);
  const T px = -P[0] / P[2];
  const T py = -P[1] / P[2];
  const T r2 = px * px + py * py;
  const T distortion = T(1.0) + r2 * (camera[7] + camera[8] * r2);
  image[0] = camera[6] * distortion * px;
  image[1] = camera[6] * distortion * py;
}

/// Whether `point` lies strictly in front of `camera` (P_z < 0 in the camera frame).
inline bool in_front_of_camera(const double* camera, const double* point) {
  double P[3];
  snavely_camera_point(camera, point, P);
  return P[2] < 0.0;
}

}  // namespace carat
