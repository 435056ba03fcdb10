// Fuzzes the g2o reader and the pose-graph builder: any input must either parse or throw
// carat::Error, never crash, hang or leak.
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include "carat/residuals/g2o_io.hpp"
#include "carat/residuals/pose_graph.hpp"
#include "carat/solver/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  try {
    const carat::PoseGraph graph = carat::parse_g2o(in, "fuzz.g2o");
    if (graph.vertices.size() < 64 && graph.edges.size() < 256) {
      (void)carat::build_pose_graph_problem(graph);
    }
  } catch (const carat::Error&) {
  }
  return 0;
}
