#pragma once

/// g2o text format for 3D pose graphs: VERTEX_SE3:QUAT, EDGE_SE3:QUAT (information upper
/// triangle, translation first, 21 numbers) and FIX records.

#include <filesystem>
#include <istream>
#include <ostream>
#include <string>
#include <string_view>
#include <vector>

#include "carat/residuals/pose_graph.hpp"

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

/// Reads a g2o file line by line (a regular file, or a FIFO or device). Throws carat::Error naming
/// the file, the line and the problem for a missing or empty file, a directory, a line longer
/// than 64 KiB or holding a NUL byte, an unknown record, a wrong number count, a non-finite number,
/// a degenerate quaternion, a duplicate vertex, an edge to a missing vertex, or (unless
/// options.information says otherwise) an information matrix that is not positive definite.
PoseGraph read_g2o(const std::filesystem::path& path, const G2oReadOptions& options = {},
                   G2oReadReport* report = nullptr);

/// Parses g2o text from a stream; `name` is used in error messages.
PoseGraph parse_g2o(std::istream& in, const std::string& name, const G2oReadOptions& options = {},
                    G2oReadReport* report = nullptr);

/// Parses g2o text held in memory; `name` is used in error messages.
PoseGraph parse_g2o(std::string_view text, const std::string& name,
                    const G2oReadOptions& options = {}, G2oReadReport* report = nullptr);

/// Writes a pose graph in g2o format atomically (temporary file, then rename); full precision.
void write_g2o(const std::filesystem::path& path, const PoseGraph& graph);

/// Writes a pose graph in g2o format to a stream; full precision.
void write_g2o(std::ostream& out, const PoseGraph& graph);

}  // namespace carat
