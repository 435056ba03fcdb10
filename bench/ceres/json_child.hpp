#pragma once
// Runs a comparison benchmark's child process (a shell command) and reads the one JSON object it
// prints, for the benches that time each solver in a process of its own.
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

/// Runs `command` (with `preload`, when not empty, as its LD_PRELOAD) and parses its standard
/// output as JSON; {"error": ...} when it cannot start, fails or prints nothing.
inline nlohmann::json run_json_child(const std::string& command, const std::string& preload) {
  const std::string line = (preload.empty() ? "" : "LD_PRELOAD='" + preload + "' ") + command;
  FILE* pipe = popen(line.c_str(), "r");
  if (!pipe) return {{"error", "cannot start " + line}};
  std::string out;
  char buffer[4096];
  while (std::fgets(buffer, sizeof(buffer), pipe)) out += buffer;
  const int status = pclose(pipe);
  if (status != 0 || out.empty()) return {{"error", "child failed: " + line}};
  return nlohmann::json::parse(out);
}
