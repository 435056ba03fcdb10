#pragma once

// Internal: OpenMP regions run inactive (single-threaded) while an object of this type lives.
// Debian's CHOLMOD runs some loops of its supernodal factorization under OpenMP with a fixed
// team size, and Eigen's matrix products in files built with OpenMP parallelize themselves; on
// small machines that oversubscribes the cores and costs more in thread wake-ups than it gains
// (measured: torus3D 1.6 s vs 1.0 s of factorization; the sparse inverse of parking-garage
// 2.1 s vs 0.04 s).

#include <omp.h>

namespace carat::internal {

class SerialOpenMp {
 public:
  SerialOpenMp() : saved_levels_(omp_get_max_active_levels()) { omp_set_max_active_levels(0); }
  ~SerialOpenMp() { omp_set_max_active_levels(saved_levels_); }
  SerialOpenMp(const SerialOpenMp&) = delete;
  SerialOpenMp& operator=(const SerialOpenMp&) = delete;

 private:
  int saved_levels_;
};

}  // namespace carat::internal
