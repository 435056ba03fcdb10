// Fuzzes the g2o reader (3D and 2D records) in memory (rejecting and repairing indefinite
// information) and the pose-graph builder: any input must either parse or throw carat::Error, never
// crash, hang or leak. Run with fuzz/g2o.dict (record names and boundary numbers).
#include <cstddef>
#include <cstdint>
#include <string_view>
#include <variant>

#include "carat/base/error.hpp"
#include "carat/residuals/io/g2o_io.hpp"
#include "carat/residuals/pose_graph.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  // Both ways of treating an indefinite information matrix: reject, and repair.
  for (const auto repair :
       {carat::InformationRepair::kReject, carat::InformationRepair::kNearest}) {
    carat::G2oReadOptions options;
    options.information = repair;
    try {
      const carat::G2oGraph any = carat::parse_g2o_any(text, "fuzz.g2o", options);
      std::visit(
          [](const auto& graph) {
            if (graph.vertices.size() < 64 && graph.edges.size() < 256) {
              (void)carat::build_pose_graph_problem(graph);
            }
          },
          any);
    } catch (const carat::Error&) {
    }
  }
  return 0;
}
