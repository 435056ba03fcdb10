#pragma once

// Fig. 6's data: a GRE solve followed iteration by iteration, with the full factors'
// registration error and the ATE at every iterate.

#include <Eigen/Geometry>
#include <span>
#include <string>
#include <vector>

#include "carat/registration/frame_store.hpp"
#include "carat/registration/global_registration.hpp"
#include "carat/registration/mapping.hpp"
#include "mapping_methods.hpp"

namespace carat::cli::paper {

/// One GRE solve, one entry per LM iteration (rejected steps repeat the accepted iterate).
struct IterationTrace {
  std::string key;             ///< method key, e.g. "gre_exact"
  std::string label;           ///< e.g. "GRE exact (M=29)"
  std::vector<int> iteration;  ///< LM iteration (0: the starting poses)
  std::vector<double> cost;    ///< the method's own objective, 1/2 sum |r|^2 of its rows
  std::vector<double> registration_error;  ///< 1/2 sum |r|^2 over every full factor's rows
  std::vector<double> ate_rmse;            ///< ATE RMSE against the reference, metres
};

/// The registration error of the full factors (correspondences fixed at the initial poses, no
/// kernel) at any poses, from their lossless rows: the same cost as all residuals, at every pose.
class RegistrationErrorProbe {
 public:
  /// Builds the lossless factors of `graph` at its start, with the correspondence distance,
  /// seed and threads of `options`.
  RegistrationErrorProbe(FrameStore& frames, const MapGraph& graph, const MappingOptions& options);

  /// 1/2 sum |r|^2 over the full factors at T_world_frame (parallel to the frames).
  double operator()(std::span<const Eigen::Isometry3d> T_world_frame);

  /// A callback that appends each iteration to *trace, with the ATE against T_world_truth;
  /// both must outlive the solve.
  RegistrationIterationCallback recorder(std::span<const Eigen::Isometry3d> T_world_truth,
                                         IterationTrace* trace);

 private:
  RegistrationProblem problem_;
};

}  // namespace carat::cli::paper
