#pragma once

/// The Python module's mapping types: the dense graph's pairs, and what the mapping calls return
/// (optimized poses and the solve, as numpy arrays and dicts).

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <string>
#include <vector>

#include "carat/registration/dense_graph.hpp"
#include "carat/solver/solver_summary.hpp"

namespace carat::python {

/// The frame pairs of a dense graph (carat.DenseGraph).
struct DenseGraph {
  std::vector<FramePair> pairs;  ///< (target, source, overlap), target < source
};

/// Poses (N x 4 x 4, T_world_frame) and the solve's summary and statistics.
struct MappingResult {
  pybind11::array_t<double> poses;         ///< optimized T_world_frame, N x 4 x 4
  pybind11::dict summary;                  ///< the solver summary (SolverSummary::to_json's fields)
  pybind11::dict stats;                    ///< what building the problem cost (method-specific)
  pybind11::array_t<double> factor_costs;  ///< per factor (GRE): squared error / correspondences
  int rounds = 0;                          ///< correspondence rounds (GRE), 0 for a pose graph
};

/// The summary as a Python dict.
pybind11::dict summary_dict(const SolverSummary& summary);

}  // namespace carat::python
