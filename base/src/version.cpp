#include "carat/base/version.hpp"

namespace carat {

const char* version() { return CARAT_VERSION; }

}  // namespace carat
