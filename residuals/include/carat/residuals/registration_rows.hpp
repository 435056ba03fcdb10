#pragma once

/// Shared machinery of the binary registration blocks (GICP, point-to-point, point-to-plane):
/// rows depend on the two poses T_world_i (target frame) and T_world_j (source frame) only
/// through T_ij = T_i^-1 T_j, so every block reports its Jacobian with respect to the right
/// tangent of T_ij (reduced dimension 6) and the fixed map A = [-Ad(T_ij^-1) | I] (6 x 12).

#include <Eigen/Geometry>

#include "carat/solver/residual_block.hpp"

namespace carat {

/// T_ij = T_i^-1 T_j from the two SE(3) parameter blocks (target pose i first, source pose j).
Eigen::Isometry3d relative_pose(ParameterPointers params);

/// Writes A = [-Ad(T_ij^-1) | I] (6 x 12, row-major), so that [J_i | J_j] = J_r A.
void relative_pose_reduced_map(ParameterPointers params, double* A);

}  // namespace carat
