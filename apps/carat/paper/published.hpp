#pragma once

// The published numbers of Koide, Oishi, Yokozuka and Banno, "Exact Point Cloud Downsampling
// for Fast and Accurate Global Trajectory Optimization" (IROS 2023), that `carat paper` shows
// beside its own. They are the paper's values as printed; every other file takes them from here.

#include <array>

namespace carat::cli::paper::published {

/// Table I: targets M of the exact sampling time (N = 30,000 rows).
inline constexpr std::array<int, 6> kTable1Rows{29, 64, 128, 256, 512, 1024};
/// Table I: time of exact sampling per M of kTable1Rows, in milliseconds.
inline constexpr std::array<double, 6> kTable1Ms{6.87, 13.39, 19.34, 25.03, 29.99, 34.19};

/// Table II: points kept by random sampling (3 residuals each).
inline constexpr std::array<int, 4> kTable2RandomPoints{10, 64, 256, 1024};
/// Table II: mean NKLD of random sampling per size of kTable2RandomPoints.
inline constexpr std::array<double, 4> kTable2RandomNkld{0.996, 0.437, 0.107, 0.024};
/// Table II: NKLD of exact sampling (29 to 3072 residuals).
inline constexpr double kTable2ExactNkld = 0.0;

/// An ATE as the paper prints it: mean and standard deviation, in metres.
struct Ate {
  double mean = 0.0;  ///< metres
  double std = 0.0;   ///< metres
};

/// Table III: the KITTI sequences, in column order.
inline constexpr std::array<const char*, 4> kTable3Sequences{"00", "02", "05", "08"};
/// Table III: ATE of PGO with identity information, per sequence of kTable3Sequences.
inline constexpr std::array<Ate, 4> kTable3PgoIdentity{
    {{1.6257, 0.7529}, {23.9856, 8.2752}, {1.5149, 0.6760}, {9.3636, 3.2890}}};
/// Table III: ATE of PGO with the GICP Hessian as information.
inline constexpr std::array<Ate, 4> kTable3PgoHessian{
    {{1.3777, 0.6051}, {9.3406, 3.1490}, {1.6249, 0.8489}, {5.0532, 2.5991}}};
/// Table III: ATE of PGO with the Hessian over the dense graph.
inline constexpr std::array<Ate, 4> kTable3PgoDense{
    {{1.1846, 0.5625}, {9.3393, 3.1486}, {1.6240, 0.8488}, {5.0520, 2.5993}}};
/// Table III: ATE of global registration error minimization with exact sampling, M = 29.
inline constexpr std::array<Ate, 4> kTable3GreExact{
    {{0.9553, 0.4650}, {8.9679, 3.0856}, {0.2917, 0.1060}, {4.4394, 2.5294}}};

/// One row of Tables IV and V (KITTI 00): a sampling setting and what it cost.
struct SamplingRow {
  int residuals = 0;                  ///< M; 0 for all residuals (~30,000 per factor)
  Ate ate;                            ///< Table IV, metres
  double hours = 0.0;                 ///< Table IV: optimization time, hours (128 threads)
  double correspondences_gb = 0.0;    ///< Table V: memory of the correspondences, GB
  double sampled_residuals_gb = 0.0;  ///< Table V: memory of the sampled residuals, GB
};

/// Tables IV and V: exact M = 29, 256, 1024, then all residuals (the original points).
inline constexpr std::array<SamplingRow, 4> kTables4And5{{
    {29, {0.9553, 0.4650}, 1.67, 0.11, 0.14},
    {256, {0.9549, 0.4646}, 1.88, 0.43, 1.15},
    {1024, {0.9549, 0.4647}, 2.36, 1.52, 4.87},
    {0, {0.9549, 0.4647}, 13.21, 25.13, 0.00},
}};

/// The problem behind Tables IV and V (KITTI 00): poses.
inline constexpr int kSequence00Poses = 4540;
/// The problem behind Tables IV and V (KITTI 00): registration factors.
inline constexpr int kSequence00Factors = 585417;
/// Threads of the paper's machine for Tables IV and V.
inline constexpr int kThreads = 128;

}  // namespace carat::cli::paper::published
