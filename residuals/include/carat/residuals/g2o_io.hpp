#pragma once

/// g2o text format for 3D pose graphs: VERTEX_SE3:QUAT, EDGE_SE3:QUAT (information upper
/// triangle, translation first, 21 numbers) and FIX records.

#include <filesystem>
#include <istream>
#include <string>

#include "carat/residuals/pose_graph.hpp"

namespace carat {

/// Reads a g2o file. Throws carat::Error naming the file, the line and the problem for a
/// missing or empty file, an unknown record, a wrong number count, a non-finite number, a
/// degenerate quaternion, a duplicate vertex, an edge to a missing vertex, or an information
/// matrix that is not positive definite.
PoseGraph read_g2o(const std::filesystem::path& path);

/// Parses g2o text from a stream; `name` is used in error messages.
PoseGraph parse_g2o(std::istream& in, const std::string& name);

/// Writes a pose graph in g2o format atomically (temporary file, then rename); full precision.
void write_g2o(const std::filesystem::path& path, const PoseGraph& graph);

}  // namespace carat
