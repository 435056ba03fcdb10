#pragma once

#include <stdexcept>
#include <string>

namespace carat {

/// The one exception type carat's libraries throw; the message names the input and the problem.
class Error : public std::runtime_error {
 public:
  /// Creates an error with a complete, human-readable message.
  explicit Error(const std::string& message) : std::runtime_error(message) {}
};

}  // namespace carat
