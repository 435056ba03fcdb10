#pragma once

// carat's version, as the build's project(VERSION) sets it.

namespace carat {

/// carat's version, "MAJOR.MINOR.PATCH" (CMake's project(VERSION) of the build that made the
/// library).
const char* version();

}  // namespace carat
