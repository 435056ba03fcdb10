#pragma once

#include <cstdio>
#include <stdexcept>
#include <string>
#include <string_view>

namespace carat {

/// The one exception type carat's libraries throw; the message names the input and the problem.
class Error : public std::runtime_error {
 public:
  /// Creates an error with a complete, human-readable message.
  explicit Error(const std::string& message) : std::runtime_error(message) {}
};

/// Bytes of an input as an error message may show them: in single quotes, printable ASCII only
/// (any other byte becomes '?'), at most `max_chars` of them (then "..."), so that a message stays
/// one short line whatever the input holds.
inline std::string quote_bytes(std::string_view bytes, std::size_t max_chars = 40) {
  std::string out = "'";
  for (std::size_t i = 0; i < bytes.size() && i < max_chars; ++i) {
    const char c = bytes[i];
    out += (c >= 0x20 && c < 0x7f) ? c : '?';
  }
  if (bytes.size() > max_chars) out += "...";
  return out + "'";
}

/// A number as a message shows it: six significant digits, as %g writes them (1e-12 stays
/// "1e-12", where std::to_string would print "0.000000").
inline std::string message_number(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.6g", value);
  return buffer;
}

}  // namespace carat
