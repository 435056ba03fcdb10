#include "carat/solver/version.hpp"

namespace carat {

const char* version() { return CARAT_VERSION; }

}  // namespace carat
