#pragma once

/// The parts of the Python module, each adding its functions and classes to the module.

#include <pybind11/pybind11.h>

namespace carat::python {

/// carat.coreset and the quadratic-model helpers.
void bind_coreset(pybind11::module_& m);
/// Point-cloud files, voxel downsampling, covariances, Frame.
void bind_clouds(pybind11::module_& m);
/// align, GicpFactor and its lossless rows.
void bind_registration(pybind11::module_& m);
/// Frames from folders or arrays, trajectories, the dense graph, optimize, pose graphs, ATE.
void bind_mapping(pybind11::module_& m);
/// solve_g2o.
void bind_solve(pybind11::module_& m);
/// Problem, solve, compress, solve_recompressed and their summaries.
void bind_problem(pybind11::module_& m);
/// The synthetic world: simulate, simulate_scans, simulate_bal.
void bind_sim(pybind11::module_& m);

}  // namespace carat::python
