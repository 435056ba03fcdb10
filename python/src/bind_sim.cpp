// The synthetic world from Python: a whole mapping setup (carat.simulate) or raw scans.
#include <pybind11/numpy.h>
#include <pybind11/stl.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <string>
#include <vector>

#include "arrays.hpp"
#include "bindings.hpp"
#include "carat/base/error.hpp"
#include "carat/base/machine_memory.hpp"
#include "carat/registration/frame.hpp"
#include "carat/sim/bal_scene.hpp"
#include "carat/sim/pipeline.hpp"
#include "carat/sim/sequence.hpp"
#include "carat/sim/world.hpp"
#include "frame_list.hpp"
#include "integer_arguments.hpp"
#include "interrupt.hpp"
#include "mapping_types.hpp"

namespace carat::python {

namespace {

/// What carat.simulate returns.
struct Simulation {
  py::array_t<double> truth;    ///< ground truth T_world_frame
  py::array_t<double> drift;    ///< the drifting guess
  py::array_t<double> initial;  ///< drift refined by odometry (the drift without odometry)
  py::tuple frames;             ///< carat.Frame per pose
  py::object graph;             ///< carat.DenseGraph at `initial`, or None
  std::size_t raw_points = 0;   ///< points of all scans before downsampling
  py::dict timings;             ///< seconds per stage
};

SyntheticWorldOptions world_options(std::uint64_t seed, int beams, int circuit_blocks) {
  SyntheticWorldOptions world;
  world.seed = seed;
  world.beams = beams;
  world.blocks_x = circuit_blocks + 1;  // a row of buildings beyond the circuit's end
  return world;
}

SyntheticTrajectoryOptions drive_options(int frames, int laps, int circuit_blocks) {
  SyntheticTrajectoryOptions drive;
  drive.frames = frames;
  drive.laps = laps;
  drive.circuit_blocks_x = circuit_blocks;
  return drive;
}

/// Refuses, before any work, a drive that would not fit the memory available, priced from its
/// first scan as `carat simulate` prices the disk: ValueError naming frames. `frame_bytes` gives
/// what the call holds per frame from that scan.
template <typename FrameBytes>
void check_drive_memory(const SyntheticWorldOptions& world_options,
                        const SyntheticTrajectoryOptions& drive, const FrameBytes& frame_bytes) {
  const SyntheticWorld world(world_options);
  const double per_frame = frame_bytes(first_scan(world, drive));
  const double bytes = static_cast<double>(drive.frames) * per_frame;
  const auto available = static_cast<double>(available_memory_bytes());
  if (bytes > 0.8 * available) {
    throw py::value_error("frames: " + std::to_string(drive.frames) + " frames would take about " +
                          format_bytes(bytes) + " of memory (" + format_bytes(per_frame) +
                          " per frame); " + format_bytes(available) +
                          " are available; use fewer frames");
  }
}

Simulation simulate(int frames, int laps, std::uint64_t seed, int beams, int circuit_blocks,
                    double voxel_size, double drift_translation, double drift_rotation_deg,
                    double drift_heading_deg, bool odometry, bool dense_graph, int threads) {
  SyntheticPipelineOptions options;
  options.world = world_options(seed, beams, circuit_blocks);
  options.drive = drive_options(frames, laps, circuit_blocks);
  // Every frame is kept preprocessed (points, covariances, k-d tree) with its share of the graph.
  check_drive_memory(options.world, options.drive, [&](PointCloud scan) {
    return 1.5 *
           static_cast<double>(
               preprocess_frame(std::move(scan), options.preprocess, "frame 0")->memory_bytes());
  });
  options.preprocess.voxel_size = voxel_size;
  options.preprocess.num_threads = threads_argument(threads);
  options.drift.translation_sigma = drift_translation;
  options.drift.rotation_sigma_deg = drift_rotation_deg;
  options.drift.heading_bias_deg = drift_heading_deg;
  options.odometry = odometry;
  options.dense_graph = dense_graph;
  options.threads = threads_argument(threads);
  const SyntheticPipeline pipeline = run_released([&](InterruptCheck& check) {
    return simulate_pipeline(options, [&](SyntheticPipelineStage, std::size_t done,
                                          std::size_t total) { check.progress()(done, total); });
  });
  Simulation out;
  out.truth = read_only(array_from_poses(pipeline.T_world_truth));
  out.drift = read_only(array_from_poses(pipeline.T_world_drift));
  out.initial = read_only(array_from_poses(pipeline.T_world_initial));
  out.frames = py::tuple(list_from_frames(pipeline.frames));
  if (dense_graph) {
    out.graph = py::cast(DenseGraph{pipeline.pairs});
  } else {
    out.graph = py::none();
  }
  out.raw_points = pipeline.raw_points;
  out.timings["simulate_s"] = pipeline.timings.simulate_s;
  out.timings["preprocess_s"] = pipeline.timings.preprocess_s;
  out.timings["initial_guess_s"] = pipeline.timings.initial_guess_s;
  out.timings["dense_graph_s"] = pipeline.timings.dense_graph_s;
  return out;
}

py::tuple simulate_scans(int frames, int laps, std::uint64_t seed, int beams, int circuit_blocks) {
  const SyntheticWorldOptions options = world_options(seed, beams, circuit_blocks);
  const SyntheticTrajectoryOptions drive = drive_options(frames, laps, circuit_blocks);
  // Every raw scan is kept, as float x, y, z.
  check_drive_memory(options, drive, [](const PointCloud& scan) {
    return 12.0 * static_cast<double>(scan.size());
  });
  // Frame by frame (each scan parallel inside), so that Ctrl-C is seen between frames.
  std::vector<PointCloud> scans_out;
  std::vector<Eigen::Isometry3d> truth;
  run_released([&](InterruptCheck& check) {
    const SyntheticWorld world(options);
    truth = world.trajectory(drive);
    const auto progress = check.progress();
    scans_out.resize(truth.size());
    tbb::parallel_for(std::size_t{0}, truth.size(), [&](std::size_t k) {
      scans_out[k] = world.scan(truth[k], synthetic_frame_noise_seed(seed, k));
      progress(k + 1, truth.size());
    });
  });
  py::list scans;
  for (PointCloud& scan : scans_out) scans.append(array_from_cloud(std::move(scan)));
  return py::make_tuple(scans, array_from_poses(truth));
}

/// A BAL problem as numpy arrays: cameras (C x 9), points (P x 3), and per observation its
/// camera and point index and the observed pixels (N x 2).
py::dict bal_arrays(const BalProblem& bal) {
  py::array_t<double> cameras({static_cast<py::ssize_t>(bal.cameras.size()), py::ssize_t{9}});
  for (std::size_t c = 0; c < bal.cameras.size(); ++c) {
    std::copy_n(bal.cameras[c].data(), 9, cameras.mutable_data() + 9 * c);
  }
  py::array_t<double> points({static_cast<py::ssize_t>(bal.points.size()), py::ssize_t{3}});
  for (std::size_t p = 0; p < bal.points.size(); ++p) {
    std::copy_n(bal.points[p].data(), 3, points.mutable_data() + 3 * p);
  }
  const auto n = static_cast<py::ssize_t>(bal.observations.size());
  py::array_t<std::int64_t> camera_index(n), point_index(n);
  py::array_t<double> observed({n, py::ssize_t{2}});
  for (py::ssize_t k = 0; k < n; ++k) {
    const BalObservation& o = bal.observations[static_cast<std::size_t>(k)];
    camera_index.mutable_data()[k] = o.camera;
    point_index.mutable_data()[k] = o.point;
    observed.mutable_data()[2 * k] = o.x;
    observed.mutable_data()[2 * k + 1] = o.y;
  }
  py::dict out;
  out["cameras"] = cameras;
  out["points"] = points;
  out["camera_index"] = camera_index;
  out["point_index"] = point_index;
  out["observed"] = observed;
  return out;
}

py::dict simulate_bal_scene(int cameras, int points, int observations_per_point,
                            const std::string& layout, double noise, double outliers,
                            double start_noise, std::uint64_t seed) {
  BalSimulationOptions options;
  try {
    options.layout = parse_bal_layout(layout);
  } catch (const Error& e) {
    throw py::value_error(std::string("simulate_bal: layout: ") + e.what());
  }
  options.cameras = cameras;
  options.points = points;
  options.observations_per_point = observations_per_point;
  options.pixel_noise_sigma = noise;
  options.outlier_fraction = outliers;
  options.camera_rotation_sigma_rad *= start_noise;
  options.camera_position_sigma_m *= start_noise;
  options.focal_sigma_relative *= start_noise;
  options.point_sigma_m *= start_noise;
  options.seed = seed;
  const BalScene scene = run_released([&](InterruptCheck&) { return simulate_bal(options); });
  py::dict out = bal_arrays(scene.problem);
  const py::dict truth = bal_arrays(scene.truth);
  out["truth_cameras"] = truth["cameras"];
  out["truth_points"] = truth["points"];
  py::array_t<bool> outlier(static_cast<py::ssize_t>(scene.outlier.size()));
  for (std::size_t k = 0; k < scene.outlier.size(); ++k) {
    outlier.mutable_data()[k] = scene.outlier[k] != 0;
  }
  out["outlier"] = outlier;
  return out;
}

}  // namespace

void bind_sim(py::module_& m) {
  py::class_<Simulation>(m, "Simulation", "A simulated drive, ready to map.")
      .def_readonly("truth", &Simulation::truth, "Ground-truth T_world_frame, N x 4 x 4")
      .def_readonly("drift", &Simulation::drift, "The drifting initial guess, N x 4 x 4")
      .def_readonly("initial", &Simulation::initial,
                    "The guess refined by GICP odometry (the drift when odometry is off)")
      .def_readonly("frames", &Simulation::frames, "The preprocessed scans (carat.Frame)")
      .def_readonly("graph", &Simulation::graph,
                    "The dense graph at `initial` (carat.DenseGraph), or None")
      .def_readonly("raw_points", &Simulation::raw_points,
                    "Points of all scans before downsampling")
      .def_readonly("timings", &Simulation::timings, "Seconds per stage");
  def_checked(
      m, "simulate", &simulate, py::arg("frames") = 100, py::arg("laps") = 2, py::arg("seed") = 1,
      py::arg("beams") = 32, py::arg("circuit_blocks") = 1, py::arg("voxel_size") = 0.5,
      py::arg("drift_translation") = 0.02, py::arg("drift_rotation_deg") = 0.1,
      py::arg("drift_heading_deg") = 0.0, py::arg("odometry") = true, py::arg("dense_graph") = true,
      py::arg("threads") = 1,
      R"(Simulates a spinning LiDAR driving `laps` times around a synthetic city block: ground
truth, preprocessed frames, a drifting initial guess (drift_translation metres and
drift_rotation_deg degrees of std-dev per metre travelled, plus a steady heading drift of
drift_heading_deg degrees per metre), refined by GICP odometry, and the
dense graph at it; the defaults are `carat demo`'s. Deterministic in seed.
Returns a carat.Simulation.)");
  def_checked(m, "simulate_scans", &simulate_scans, py::arg("frames") = 100, py::arg("laps") = 2,
              py::arg("seed") = 1, py::arg("beams") = 32, py::arg("circuit_blocks") = 1,
              "Raw scans of a simulated drive: (list of N x 3 float32 arrays in the sensor frame, "
              "ground-truth T_world_frame N x 4 x 4).");
  def_checked(
      m, "simulate_bal", &simulate_bal_scene, py::arg("cameras") = 16, py::arg("points") = 1000,
      py::arg("observations_per_point") = 4, py::arg("layout") = "ring", py::arg("noise") = 1.0,
      py::arg("outliers") = 0.0, py::arg("start_noise") = 1.0, py::arg("seed") = 1,
      R"(A synthetic bundle-adjustment problem in the BAL camera model, as `carat simulate-bal`
writes it (same options, same seed, same numbers). Returns a dict: cameras (C x 9: angle-axis
w, t, f, k1, k2), points (P x 3), camera_index and point_index (one per observation), observed
(N x 2 pixels), truth_cameras, truth_points, outlier (N booleans).)");
}

}  // namespace carat::python
