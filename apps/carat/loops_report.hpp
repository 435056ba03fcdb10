#pragma once

// The loop step of `carat map` and `carat demo` in their reports: the JSON object and the line
// of text.

#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "carat/registration/loop_closure.hpp"

namespace carat::cli {

/// {"ran": false} when `loops` is empty; else ran, candidates, accepted, rejected (per verdict),
/// sparse_frames, time_s, pairs (the accepted loops' frames) and, when loops were accepted,
/// the pose graph's termination, iterations, final_cost and time_s under "pgo".
nlohmann::json loops_json(const std::optional<LoopClosureResult>& loops, double time_s);

/// One line of the text report: how many candidates GICP accepted and the pose graph's end, or
/// that none were found, plus the frames too sparse for a descriptor.
std::string loops_line(const LoopClosureResult& loops);

}  // namespace carat::cli
