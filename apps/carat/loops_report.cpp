#include "loops_report.hpp"

#include <cstddef>

namespace carat::cli {

nlohmann::json loops_json(const std::optional<LoopClosureResult>& loops, double time_s) {
  nlohmann::json j = {{"ran", loops.has_value()}};
  if (!loops) return j;
  nlohmann::json rejected = nlohmann::json::object();
  for (LoopVerdict v : {LoopVerdict::kNotConverged, LoopVerdict::kDegenerate,
                        LoopVerdict::kFewInliers, LoopVerdict::kTooFarFromGuess}) {
    std::size_t count = 0;
    for (const LoopCheck& check : loops->checks) count += check.verdict == v;
    rejected[to_string(v)] = count;
  }
  j["candidates"] = loops->candidates.size();
  j["accepted"] = loops->loops.size();
  j["rejected"] = rejected;
  j["sparse_frames"] = loops->sparse_frames.size();
  j["time_s"] = time_s;
  nlohmann::json accepted = nlohmann::json::array();
  for (const PairRegistration& loop : loops->loops)
    accepted.push_back({loop.pair.target, loop.pair.source});
  j["pairs"] = accepted;
  if (!loops->loops.empty()) {
    j["pgo"] = {{"termination", to_string(loops->summary.termination)},
                {"iterations", loops->summary.num_iterations},
                {"final_cost", loops->summary.final_cost},
                {"time_s", loops->summary.time.total_s}};
  }
  return j;
}

std::string loops_line(const LoopClosureResult& loops) {
  std::string line;
  if (!loops.loops.empty()) {
    line = "  loops: " + std::to_string(loops.loops.size()) + " of " +
           std::to_string(loops.candidates.size()) +
           " Scan Context candidates accepted by GICP; pose graph " +
           to_string(loops.summary.termination);
  } else {
    line = "  loops: none found (" + std::to_string(loops.candidates.size()) +
           " candidates, none validated): the start is left as it is, and a drive whose loops "
           "are not closed may stay inconsistent";
  }
  if (!loops.sparse_frames.empty()) {
    line +=
        "; " + std::to_string(loops.sparse_frames.size()) + " frames too sparse for a descriptor";
  }
  return line;
}

}  // namespace carat::cli
