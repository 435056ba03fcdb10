// The dense global-registration pipeline from Python: frames, trajectories, the dense graph,
// optimize (full / exact / lossless / random rows), the pose-graph baselines and the ATE.
#include <pybind11/numpy.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "arrays.hpp"
#include "bindings.hpp"
#include "carat/base/error.hpp"
#include "carat/registration/dense_graph.hpp"
#include "carat/registration/frame.hpp"
#include "carat/registration/global_registration.hpp"
#include "carat/registration/io/scan_folder.hpp"
#include "carat/registration/io/trajectory_io.hpp"
#include "carat/registration/loop_closure.hpp"
#include "carat/registration/mapping.hpp"
#include "carat/registration/odometry.hpp"
#include "carat/registration/pair_registration.hpp"
#include "carat/registration/pose_graph_baseline.hpp"
#include "carat/registration/scan_opening.hpp"
#include "carat/registration/trajectory_error.hpp"
#include "frame_list.hpp"
#include "integer_arguments.hpp"
#include "interrupt.hpp"
#include "mapping_types.hpp"

namespace carat::python {

pybind11::dict summary_dict(const SolverSummary& summary) {
  return py::module_::import("json").attr("loads")(summary.to_json());
}

namespace {

PreprocessOptions preprocess_options(double voxel_size, int neighbors, int min_points,
                                     int threads) {
  PreprocessOptions options;
  options.voxel_size = voxel_size;
  options.covariance_neighbors = neighbors_argument(neighbors);
  options.min_points = min_points;
  options.num_threads = threads_argument(threads);
  return options;
}

/// Pairs from a DenseGraph or a P x 2 array of (target, source) frame indices, target < source.
std::vector<FramePair> pairs_argument(const py::handle& obj, std::size_t num_frames) {
  if (py::isinstance<DenseGraph>(obj)) return obj.cast<const DenseGraph&>().pairs;
  const auto array = as_float64(obj, "pairs");
  if (array.ndim() != 2 || array.shape(1) != 2) {
    throw py::value_error("pairs: expected a carat.DenseGraph or a P x 2 array of frame indices");
  }
  std::vector<FramePair> pairs(static_cast<std::size_t>(array.shape(0)));
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    const double i = array.data()[2 * k];
    const double j = array.data()[2 * k + 1];
    const auto n = static_cast<double>(num_frames);
    if (!(i >= 0 && i < n && j >= 0 && j < n) || i != std::floor(i) || j != std::floor(j)) {
      throw py::value_error("pairs[" + std::to_string(k) +
                            "]: frame indices must be integers in [0, " +
                            std::to_string(num_frames) + ")");
    }
    if (!(i < j)) {
      throw py::value_error("pairs[" + std::to_string(k) +
                            "]: the target index must be below the source index");
    }
    pairs[k] = {static_cast<int>(i), static_cast<int>(j), 0.0};
  }
  return pairs;
}

std::vector<Eigen::Isometry3d> poses_for_frames(const py::handle& obj, std::size_t num_frames) {
  auto poses = poses_from_array(obj, "poses");
  if (poses.size() != num_frames) {
    throw py::value_error("poses: " + std::to_string(poses.size()) + " poses for " +
                          std::to_string(num_frames) + " frames");
  }
  return poses;
}

/// The mapping pipeline's options for one call: `threads` everywhere, LM up to max_iterations.
MappingOptions mapping_options(int threads, int max_iterations) {
  MappingOptions options;
  options.num_threads = threads_argument(threads);
  options.registration.solver.max_iterations = max_iterations;
  options.pose_graph.solver.max_iterations = max_iterations;
  return options;
}

/// The interruption check as the mapping pipeline's progress callback.
MappingProgress mapping_progress(InterruptCheck& check) {
  return [progress = check.progress()](MappingStage, std::size_t done, std::size_t total) {
    progress(done, total);
  };
}

/// The dense graph of a call: `pairs` from `poses`.
MapGraph map_graph(std::vector<FramePair> pairs, std::vector<Eigen::Isometry3d> poses) {
  MapGraph graph;
  graph.pairs = std::move(pairs);
  graph.T_world_start = std::move(poses);
  return graph;
}

MappingResult optimize(const py::handle& frames_in, const py::handle& graph,
                       const py::handle& poses_in, const std::string& sampling, int residuals,
                       double max_correspondence_distance, std::uint64_t seed, int threads,
                       int rounds, int max_iterations, double factor_cauchy_scale,
                       double factor_excess_cauchy_scale) {
  FrameStore frames(frames_from_sequence(frames_in, "frames"));
  MapGraph map =
      map_graph(pairs_argument(graph, frames.size()), poses_for_frames(poses_in, frames.size()));
  MappingOptions options = mapping_options(threads, max_iterations);
  GlobalRegistrationOptions& gre = options.registration;
  gre.sampling = parse_residual_sampling(sampling);
  gre.residuals = residuals;
  gre.max_correspondence_distance = max_correspondence_distance;
  gre.seed = seed;
  gre.rounds = rounds;
  gre.factor_cauchy_scale = factor_cauchy_scale;
  gre.factor_excess_cauchy_scale = factor_excess_cauchy_scale;
  const carat::MappingResult result = run_released([&](InterruptCheck& check) {
    options.registration.solver.iteration_callback = check.iteration_callback();
    return optimize_map(frames, std::move(map), options, mapping_progress(check));
  });
  MappingResult out;
  out.poses = read_only(array_from_poses(result.T_world_frame));
  out.summary = summary_dict(result.summary);
  const RegistrationFactorStats& s = result.factor_stats;
  out.stats["factors"] = s.num_factors;
  out.stats["correspondences"] = s.num_correspondences;
  out.stats["rows"] = s.num_rows;
  out.stats["correspondence_bytes"] = s.correspondence_bytes;
  out.stats["residual_bytes"] = s.residual_bytes;
  out.stats["correspondence_s"] = s.correspondence_s;
  out.stats["compression_s"] = s.compression_s;
  out.stats["minimum_s"] = s.minimum_s;
  out.factor_costs = read_only(array_from_vector(result.factor_costs));
  out.rounds = result.rounds;
  return out;
}

MappingResult pose_graph(const py::handle& frames_in, const py::handle& graph,
                         const py::handle& poses_in, const std::string& information,
                         double cauchy_scale, double max_correspondence_distance,
                         int max_iterations, int threads) {
  FrameStore frames(frames_from_sequence(frames_in, "frames"));
  MapGraph map =
      map_graph(pairs_argument(graph, frames.size()), poses_for_frames(poses_in, frames.size()));
  const std::size_t num_pairs = map.pairs.size();
  MappingOptions options = mapping_options(threads, max_iterations);
  options.method = MappingMethod::kPoseGraph;
  options.pose_graph.information = parse_pose_graph_information(information);
  options.pose_graph.cauchy_scale = cauchy_scale;
  options.pair_alignment.max_correspondence_distance = max_correspondence_distance;
  const carat::MappingResult result = run_released([&](InterruptCheck& check) {
    options.pose_graph.solver.iteration_callback = check.iteration_callback();
    return optimize_map(frames, std::move(map), options, mapping_progress(check));
  });
  double registration_s = 0.0;
  for (const PairRegistration& r : result.registrations) registration_s += r.align_s;
  MappingResult out;
  out.poses = read_only(array_from_poses(result.T_world_frame));
  out.summary = summary_dict(result.summary);
  out.stats["factors"] = num_pairs;
  out.stats["unconverged_pairs"] = result.unconverged_pairs;
  out.stats["registration_s"] = registration_s;
  out.factor_costs = py::array_t<double>(0);
  return out;
}

py::dict close_loops_py(const py::handle& frames_in, const py::handle& poses_in,
                        double exclude_recent_m, double max_descriptor_distance,
                        double min_inlier_fraction, double max_correspondence_distance, int threads,
                        double max_drift_fraction) {
  FrameStore frames(frames_from_sequence(frames_in, "frames"));
  const auto poses = poses_for_frames(poses_in, frames.size());
  LoopClosureOptions options;
  options.exclude_recent_m = exclude_recent_m;
  options.max_descriptor_distance = max_descriptor_distance;
  options.min_inlier_fraction = min_inlier_fraction;
  options.max_correspondence_distance = max_correspondence_distance;
  options.max_drift_fraction = max_drift_fraction;
  options.num_threads = threads_argument(threads);
  const LoopClosureResult result = run_released([&](InterruptCheck& check) {
    options.graph.solver.iteration_callback = check.iteration_callback();
    return close_loops(frames, poses, options, check.progress());
  });
  py::dict out;
  out["poses"] = array_from_poses(result.T_world_frame);
  py::list candidates;
  for (const LoopCheck& c : result.checks) {
    py::dict d;
    d["target"] = c.candidate.pair.target;
    d["source"] = c.candidate.pair.source;
    d["descriptor_distance"] = c.candidate.descriptor_distance;
    d["yaw"] = c.candidate.yaw;
    d["verdict"] = to_string(c.verdict);
    d["inlier_fraction"] = c.inlier_fraction;
    d["T_target_source"] = array_from_pose(c.registration.T_target_source);
    candidates.append(d);
  }
  out["candidates"] = candidates;
  py::array_t<std::int64_t> loops({static_cast<py::ssize_t>(result.loops.size()), py::ssize_t{2}});
  for (std::size_t k = 0; k < result.loops.size(); ++k) {
    loops.mutable_data()[2 * k] = result.loops[k].pair.target;
    loops.mutable_data()[2 * k + 1] = result.loops[k].pair.source;
  }
  out["loops"] = loops;
  out["sparse_frames"] = result.sparse_frames;
  out["summary"] =
      result.loops.empty() ? py::object(py::none()) : py::object(summary_dict(result.summary));
  return out;
}

py::object odometry_py(const py::handle& frames_in, double max_correspondence_distance, int threads,
                       bool allow_unconverged, bool steps) {
  FrameStore frames(frames_from_sequence(frames_in, "frames"));
  AlignSettings settings;
  settings.max_correspondence_distance = max_correspondence_distance;
  settings.num_threads = threads_argument(threads);
  const OdometryResult result = run_released(
      [&](InterruptCheck& check) { return run_scan_odometry(frames, settings, check.progress()); });
  // A step that did not converge (or fixes fewer than 6 directions) makes every later pose wrong.
  if (result.unreliable_steps() > 0 && !allow_unconverged) {
    throw Error("odometry: " + std::to_string(result.unreliable_steps()) + " of " +
                std::to_string(result.steps.size()) +
                " steps cannot be trusted, so every pose after the first of them would be wrong: " +
                result.describe_unreliable_steps(frames) +
                " (allow_unconverged=True returns the poses anyway; steps=True reports each step)");
  }
  py::array_t<double> poses = array_from_poses(result.T_world_frame);
  if (!steps) return poses;
  const auto n = static_cast<py::ssize_t>(result.steps.size());
  py::array_t<bool> converged(n), reliable(n);
  py::array_t<std::int64_t> constrained_dof(n), iterations(n), correspondences(n);
  for (py::ssize_t k = 0; k < n; ++k) {
    const PairRegistration& step = result.steps[static_cast<std::size_t>(k)];
    converged.mutable_data()[k] = step.converged;
    reliable.mutable_data()[k] = step.reliable();
    constrained_dof.mutable_data()[k] = step.constrained_dof;
    iterations.mutable_data()[k] = step.iterations;
    correspondences.mutable_data()[k] = step.num_correspondences;
  }
  py::dict report;
  report["converged"] = converged;
  report["constrained_dof"] = constrained_dof;
  report["reliable"] = reliable;
  report["iterations"] = iterations;
  report["correspondences"] = correspondences;
  return py::make_tuple(poses, report);
}

py::dict ate(const py::handle& estimate_in, const py::handle& reference_in, bool align) {
  const auto estimate = poses_from_array(estimate_in, "estimate");
  const auto reference = poses_from_array(reference_in, "reference");
  AteOptions options;
  options.align = align;
  const AteStatistics s = compute_ate(estimate, reference, options);
  py::dict out;
  out["rmse"] = s.rmse;
  out["mean"] = s.mean;
  out["median"] = s.median;
  out["std"] = s.std;
  out["min"] = s.min;
  out["max"] = s.max;
  out["rotation_rmse_deg"] = s.rotation_rmse_deg;
  out["rotation_mean_deg"] = s.rotation_mean_deg;
  out["rotation_max_deg"] = s.rotation_max_deg;
  out["num_poses"] = s.num_poses;
  out["T_reference_estimate"] = array_from_pose(s.T_reference_estimate);
  return out;
}

}  // namespace

void bind_mapping(py::module_& m) {
  def_checked(
      m, "load_frames",
      [](const std::filesystem::path& folder, double voxel_size, int neighbors, int min_points,
         int threads, const std::string& layout) {
        OpenScansOptions options;
        options.preprocess = preprocess_options(voxel_size, neighbors, min_points, threads);
        options.num_threads = threads_argument(threads);
        options.require_constrained = false;  // the stages report degenerate frames themselves
        std::vector<ScanFile> scans = list_scan_folder(folder, parse_bin_layout(layout));
        std::vector<std::shared_ptr<const Frame>> frames;
        run_released([&](InterruptCheck& check) {
          const std::shared_ptr<FrameStore> store =
              open_scans(std::move(scans), options, check.progress());
          for (std::size_t k = 0; k < store->size(); ++k) frames.push_back(store->get(k));
        });
        return list_from_frames(frames);
      },
      py::arg("folder"), py::arg("voxel_size") = 0.25, py::arg("neighbors") = 10,
      py::arg("min_points") = 29, py::arg("threads") = 1, py::arg("layout") = "auto",
      "Reads and preprocesses every scan of a folder (DIR/*.bin|*.pcd|*.ply or "
      "DIR/<frame>/points.bin, natural name order) into a list of carat.Frame.");
  def_checked(
      m, "preprocess_frames",
      [](const py::handle& clouds_in, double voxel_size, int neighbors, int min_points,
         int threads) {
        if (!py::isinstance<py::sequence>(clouds_in)) {
          throw py::type_error("clouds: expected a sequence of N x 3 arrays");
        }
        const auto sequence = py::reinterpret_borrow<py::sequence>(clouds_in);
        std::vector<PointCloud> clouds;
        clouds.reserve(sequence.size());
        for (std::size_t k = 0; k < sequence.size(); ++k) {
          clouds.push_back(cloud_from_array(sequence[k], "clouds[" + std::to_string(k) + "]"));
        }
        const PreprocessOptions options =
            preprocess_options(voxel_size, neighbors, min_points, threads);
        auto frames = run_released([&](InterruptCheck& check) {
          return preprocess_frames(
              clouds.size(), [&](std::size_t k) { return std::move(clouds[k]); },
              [](std::size_t k) { return "clouds[" + std::to_string(k) + "]"; }, options, threads,
              check.progress());
        });
        return list_from_frames(frames);
      },
      py::arg("clouds"), py::arg("voxel_size") = 0.25, py::arg("neighbors") = 10,
      py::arg("min_points") = 29, py::arg("threads") = 1,
      "Preprocesses a sequence of N x 3 arrays (metres, each in its own frame) in parallel into "
      "a list of carat.Frame.");

  def_checked(
      m, "read_trajectory",
      [](const std::filesystem::path& path, const std::string& format) {
        const Trajectory t = read_trajectory(path, parse_trajectory_format(format));
        return array_from_poses(t.poses);
      },
      py::arg("path"), py::arg("format") = "kitti",
      "Reads T_world_frame poses ('kitti', 'tum' or 'graph') as an N x 4 x 4 array.");
  def_checked(
      m, "write_trajectory",
      [](const std::filesystem::path& path, const py::handle& poses, const std::string& format,
         const std::optional<std::vector<double>>& stamps) {
        Trajectory t;
        t.poses = poses_from_array(poses, "poses");
        if (stamps) {
          t.stamps = *stamps;
        } else {
          for (std::size_t i = 0; i < t.poses.size(); ++i)
            t.stamps.push_back(static_cast<double>(i));
        }
        write_trajectory(path, t, parse_trajectory_format(format));
      },
      py::arg("path"), py::arg("poses"), py::arg("format") = "kitti",
      py::arg("stamps") = py::none(),
      "Writes N x 4 x 4 poses atomically (stamps default to 0, 1, 2, ...).");

  py::class_<DenseGraph>(m, "DenseGraph",
                         "Frame pairs with a factor: every consecutive pair and every pair "
                         "whose scans overlap enough.")
      .def_property_readonly(
          "pairs",
          [](const DenseGraph& g) {
            py::array_t<std::int64_t> out(
                {static_cast<py::ssize_t>(g.pairs.size()), py::ssize_t{2}});
            for (std::size_t k = 0; k < g.pairs.size(); ++k) {
              out.mutable_data()[2 * k] = g.pairs[k].target;
              out.mutable_data()[2 * k + 1] = g.pairs[k].source;
            }
            return out;
          },
          "P x 2 array of (target, source) frame indices, target < source")
      .def_property_readonly(
          "overlaps",
          [](const DenseGraph& g) {
            py::array_t<double> out(static_cast<py::ssize_t>(g.pairs.size()));
            for (std::size_t k = 0; k < g.pairs.size(); ++k)
              out.mutable_data()[k] = g.pairs[k].overlap;
            return out;
          },
          "Overlap fraction of each pair at the poses the graph was built at")
      .def("__len__", [](const DenseGraph& g) { return g.pairs.size(); });

  def_checked(
      m, "dense_graph",
      [](const py::handle& frames_in, const py::handle& poses_in, double overlap_threshold,
         double voxel_size, double max_distance, int overlap_stride, int threads) {
        FrameStore frames(frames_from_sequence(frames_in, "frames"));
        const auto poses = poses_for_frames(poses_in, frames.size());
        DenseGraphOptions options;
        options.overlap_threshold = overlap_threshold;
        options.voxel_size = voxel_size;
        options.max_distance = max_distance;
        options.overlap_stride = overlap_stride;
        options.num_threads = threads_argument(threads);
        return run_released([&](InterruptCheck& check) {
          return DenseGraph{build_dense_graph(frames, poses, options, check.progress())};
        });
      },
      py::arg("frames"), py::arg("poses"), py::arg("overlap_threshold") = 0.2,
      py::arg("voxel_size") = 1.0, py::arg("max_distance") = 100.0, py::arg("overlap_stride") = 4,
      py::arg("threads") = 1,
      "The dense graph at poses (N x 4 x 4 T_world_frame): consecutive pairs and pairs whose "
      "overlap is at least overlap_threshold.");

  py::class_<MappingResult>(m, "MappingResult", "Optimized poses and the solve.")
      .def_readonly("poses", &MappingResult::poses, "Optimized T_world_frame, N x 4 x 4")
      .def_readonly("summary", &MappingResult::summary,
                    "The solver summary: termination, initial_cost, final_cost, iterations, "
                    "time_s, time_breakdown, ...")
      .def_readonly("stats", &MappingResult::stats, "What building the problem cost")
      .def_readonly("factor_costs", &MappingResult::factor_costs,
                    "Per factor (global registration): squared error / correspondences")
      .def_readonly("rounds", &MappingResult::rounds, "Correspondence rounds run");

  def_checked(m, "optimize", &optimize, py::arg("frames"), py::arg("graph"), py::arg("poses"),
              py::arg("sampling") = "exact", py::arg("residuals") = 29,
              py::arg("max_correspondence_distance") = 1.0, py::arg("seed") = 1,
              py::arg("threads") = 1, py::arg("rounds") = 1, py::arg("max_iterations") = 100,
              py::arg("factor_cauchy_scale") = 0.0, py::arg("factor_excess_cauchy_scale") = 0.0,
              R"(Global registration error minimization over the dense graph.

frames: list of carat.Frame; graph: carat.DenseGraph or P x 2 frame indices; poses: the
initial T_world_frame (N x 4 x 4; the first pose is held constant). sampling: 'full' (every
row), 'exact' (a coreset of `residuals` rows per factor, same H, b, c at the initial poses),
'lossless' (at most 13 rows with the same cost at every pose) or 'random'.
Returns a carat.MappingResult.)");
  def_checked(m, "pose_graph", &pose_graph, py::arg("frames"), py::arg("graph"), py::arg("poses"),
              py::arg("information") = "hessian", py::arg("cauchy_scale") = 1.0,
              py::arg("max_correspondence_distance") = 1.0, py::arg("max_iterations") = 100,
              py::arg("threads") = 1,
              "The pose-graph baseline: GICP for every graph pair from the initial poses, then one "
              "relative-pose factor per pair ('hessian' or 'identity' information, Cauchy kernel). "
              "Returns a carat.MappingResult.");
  def_checked(m, "close_loops", &close_loops_py, py::arg("frames"), py::arg("poses"),
              py::arg("exclude_recent_m") = 100.0, py::arg("max_descriptor_distance") = 0.35,
              py::arg("min_inlier_fraction") = 0.8, py::arg("max_correspondence_distance") = 1.0,
              py::arg("threads") = 1, py::arg("max_drift_fraction") = 0.1,
              R"(Closes the loops of a drive from a drifting guess (N x 4 x 4 T_world_frame).

Scan Context candidates (each frame's best match at least exclude_recent_m back along the
path), validated by GICP (converged, 6 directions fixed, min_inlier_fraction of the source's
points within max_correspondence_distance, moving the newer frame from the guess by at most
max_drift_fraction of the path between the two), then a pose graph of consecutive GICP and the
accepted loops. Returns a dict: poses (the pose graph's result; the guess when no loop was
accepted), candidates (target, source, descriptor_distance, yaw, verdict, inlier_fraction,
T_target_source each), loops (K x 2), sparse_frames, summary (None without loops).)");
  def_checked(m, "odometry", &odometry_py, py::arg("frames"),
              py::arg("max_correspondence_distance") = 1.0, py::arg("threads") = 1,
              py::arg("allow_unconverged") = false, py::arg("steps") = false,
              R"(GICP odometry of frames in order (each from the previous motion, a coarse then a
fine pass), chained from the identity: N x 4 x 4 T_world_frame.

A step that did not converge, or whose scans fix fewer than 6 directions (a plane), makes
every later pose wrong: it raises carat.Error naming its frames unless allow_unconverged.
steps=True returns (poses, steps) instead, steps a dict of N - 1 arrays, entry k for frame
k + 1 aligned to frame k: converged, constrained_dof, reliable (both), iterations,
correspondences.)");
  def_checked(
      m, "ate", &ate, py::arg("estimate"), py::arg("reference"), py::arg("align") = true,
      "Absolute trajectory error of N x 4 x 4 poses against a reference (pose k with pose k): "
      "rmse, mean, median, std, min, max (metres), rotation errors (degrees), after a rigid "
      "Umeyama alignment unless align is False.");
}

}  // namespace carat::python
