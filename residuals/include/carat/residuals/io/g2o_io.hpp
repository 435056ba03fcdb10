#pragma once

/// g2o text format for pose graphs: 3D (VERTEX_SE3:QUAT, EDGE_SE3:QUAT with the information
/// upper triangle, translation first, 21 numbers), 2D (VERTEX_SE2 id x y theta, EDGE_SE2 i j x y
/// theta with the information upper triangle in the order x, y, theta, 6 numbers) and FIX
/// records. One file holds one dimension.

#include <filesystem>
#include <istream>
#include <ostream>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "carat/residuals/pose_graph.hpp"
#include "carat/residuals/pose_graph_se2.hpp"

namespace carat {

/// What the reader does with an edge whose information matrix is not positive definite.
enum class InformationRepair {
  kReject,   ///< throw, naming the file and the line (the default)
  kNearest,  ///< use the nearest positive-definite matrix (see G2oReadOptions)
};

/// Options of read_g2o / parse_g2o.
struct G2oReadOptions {
  /// kNearest replaces a symmetric information matrix that is not positive definite by
  /// V max(Lambda, 1e-9 lambda_max) V^T from its eigen-decomposition V Lambda V^T (the nearest
  /// positive-definite matrix with eigenvalues at least 1e-9 of the largest). A matrix with no
  /// positive eigenvalue, or not symmetric, is still an error. Some public graphs (SE-Sync's
  /// cubicle.g2o) carry indefinite information blocks.
  InformationRepair information = InformationRepair::kReject;
};

/// What the reader changed (filled when a report is passed).
struct G2oReadReport {
  std::vector<std::size_t> repaired_lines;  ///< lines whose information matrix was replaced
};

/// A g2o pose graph of either dimension.
using G2oGraph = std::variant<PoseGraph, PoseGraphSE2>;

/// Reads a 3D g2o file line by line (a regular file, or a FIFO or device). Throws carat::Error
/// naming the file, the line and the problem for a missing or empty file, a directory, a line
/// longer than 64 KiB or holding a NUL byte, an unknown record, a 2D record, a wrong number count,
/// a non-finite number, a degenerate quaternion, a duplicate vertex, an edge to a missing vertex,
/// or (unless options.information says otherwise) an information matrix that is not positive
/// definite.
PoseGraph read_g2o(const std::filesystem::path& path, const G2oReadOptions& options = {},
                   G2oReadReport* report = nullptr);

/// Parses g2o text from a stream; `name` is used in error messages.
PoseGraph parse_g2o(std::istream& in, const std::string& name, const G2oReadOptions& options = {},
                    G2oReadReport* report = nullptr);

/// Parses g2o text held in memory; `name` is used in error messages.
PoseGraph parse_g2o(std::string_view text, const std::string& name,
                    const G2oReadOptions& options = {}, G2oReadReport* report = nullptr);

/// Reads a 2D g2o file (VERTEX_SE2 / EDGE_SE2 / FIX), with the errors of read_g2o (a 3D record
/// is one). A file with edges but no VERTEX_SE2 record gets its initial poses by
/// compose_odometry (pose_graph_se2.hpp); ids no odometry chain reaches are an error.
PoseGraphSE2 read_g2o_se2(const std::filesystem::path& path, const G2oReadOptions& options = {},
                          G2oReadReport* report = nullptr);

/// Parses 2D g2o text held in memory; `name` is used in error messages.
PoseGraphSE2 parse_g2o_se2(std::string_view text, const std::string& name,
                           const G2oReadOptions& options = {}, G2oReadReport* report = nullptr);

/// Reads a g2o file of either dimension; the first vertex or edge record decides which, and a
/// record of the other dimension is an error naming its line. A file with neither is read as 3D.
G2oGraph read_g2o_any(const std::filesystem::path& path, const G2oReadOptions& options = {},
                      G2oReadReport* report = nullptr);

/// Parses g2o text of either dimension held in memory; `name` is used in error messages.
G2oGraph parse_g2o_any(std::string_view text, const std::string& name,
                       const G2oReadOptions& options = {}, G2oReadReport* report = nullptr);

/// Writes a pose graph in g2o format atomically (temporary file, then rename); full precision.
void write_g2o(const std::filesystem::path& path, const PoseGraph& graph);

/// Writes a pose graph in g2o format to a stream; full precision.
void write_g2o(std::ostream& out, const PoseGraph& graph);

/// Writes a 2D pose graph in g2o format atomically (temporary file, then rename); full precision,
/// headings in (-pi, pi].
void write_g2o(const std::filesystem::path& path, const PoseGraphSE2& graph);

/// Writes a 2D pose graph in g2o format to a stream; full precision, headings in (-pi, pi].
void write_g2o(std::ostream& out, const PoseGraphSE2& graph);

}  // namespace carat
