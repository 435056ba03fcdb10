#include "schur_kernels.hpp"

#include "carat/base/multiversion.hpp"

namespace carat::internal {
namespace {

/// scatter_rows for cameras of DC and points of 3, with the row count fixed when it is two.
template <int DC>
__attribute__((always_inline)) inline void scatter_rows_to_points_of_3(
    const double* J, const double* r, int n, int D, int pt_local, int cam_local, double* V,
    double* g, double* W, double* slot, bool assign_w) {
  if (n == 2 && assign_w) {
    scatter_rows<DC, 3, 2, true>(J, r, n, D, pt_local, cam_local, DC, 3, V, g, W, slot);
  } else if (n == 2) {
    scatter_rows<DC, 3, 2>(J, r, n, D, pt_local, cam_local, DC, 3, V, g, W, slot);
  } else if (assign_w) {
    scatter_rows<DC, 3, 0, true>(J, r, n, D, pt_local, cam_local, DC, 3, V, g, W, slot);
  } else {
    scatter_rows<DC, 3>(J, r, n, D, pt_local, cam_local, DC, 3, V, g, W, slot);
  }
}

}  // namespace

CARAT_MULTIVERSION void scatter_rows_9_3(const double* J, const double* r, int n, int D,
                                         int pt_local, int cam_local, double* V, double* g,
                                         double* W, double* slot, bool assign_w) {
  if (n == 2 && D == 12 && cam_local == 0 && pt_local == 9) {
    if (assign_w) {
      scatter_two_rows_9_3<true>(J, r, V, g, W, slot);
    } else {
      scatter_two_rows_9_3<false>(J, r, V, g, W, slot);
    }
  } else {
    scatter_rows_to_points_of_3<9>(J, r, n, D, pt_local, cam_local, V, g, W, slot, assign_w);
  }
}

CARAT_MULTIVERSION void scatter_standard_chunk_9_3(
    std::size_t p0, std::size_t p1, const std::size_t* q_begin, const std::size_t* edge_of_q,
    const std::size_t* w_offset, const std::size_t* slot_of_edge, const std::size_t* v_offset,
    const int* pt_offset, const double* J, double* v, double* gradient, double* w, double* slots) {
  const std::size_t q0 = q_begin[p0];
  for (std::size_t p = p0; p < p1; ++p) {
    double* V = v + v_offset[p];
    for (int a = 0; a < 9; ++a) V[a] = 0.0;
    double* g = gradient + pt_offset[p];
    for (std::size_t q = q_begin[p]; q < q_begin[p + 1]; ++q) {
      const std::size_t e = edge_of_q[q];
      const double* rows = J + 26 * (q - q0);
      scatter_two_rows_9_3<true>(rows, rows + 24, V, g, w + w_offset[e], slots + slot_of_edge[e]);
    }
  }
}

CARAT_MULTIVERSION void scatter_rows_6_3(const double* J, const double* r, int n, int D,
                                         int pt_local, int cam_local, double* V, double* g,
                                         double* W, double* slot, bool assign_w) {
  scatter_rows_to_points_of_3<6>(J, r, n, D, pt_local, cam_local, V, g, W, slot, assign_w);
}

}  // namespace carat::internal
