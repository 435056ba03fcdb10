#include "cholmod_session.hpp"

#include <cholmod.h>

#include <algorithm>
#include <string>

#include "carat/base/error.hpp"
#include "serial_openmp.hpp"

namespace carat::internal {

struct CholmodSession::State {
  cholmod_common common{};
  cholmod_sparse matrix{};
  cholmod_factor* factor = nullptr;
  cholmod_dense* dense_rhs = nullptr;
  cholmod_dense* dense_x = nullptr;
  cholmod_dense* dense_y = nullptr;  // workspaces of cholmod_l_solve2
  cholmod_dense* dense_e = nullptr;

  State() {
    cholmod_l_start(&common);
    common.print = 0;  // library code never prints
    common.error_handler = nullptr;
  }
  ~State() {
    cholmod_l_free_dense(&dense_rhs, &common);
    cholmod_l_free_dense(&dense_x, &common);
    cholmod_l_free_dense(&dense_y, &common);
    cholmod_l_free_dense(&dense_e, &common);
    cholmod_l_free_factor(&factor, &common);
    cholmod_l_finish(&common);
  }
};

CholmodSession::CholmodSession() : state_(std::make_unique<State>()) {}

CholmodSession::~CholmodSession() = default;

cholmod_common& CholmodSession::common() { return state_->common; }

cholmod_factor* CholmodSession::factor() { return state_->factor; }

void CholmodSession::set_lower_matrix(std::size_t n, const std::int64_t* colptr,
                                      const std::int64_t* rows, double* values, std::size_t nnz) {
  State& st = *state_;
  st.matrix.nrow = n;
  st.matrix.ncol = n;
  st.matrix.nzmax = nnz;
  // CHOLMOD's header has no const members; it reads, never writes, a packed matrix's pattern.
  st.matrix.p = const_cast<std::int64_t*>(colptr);
  st.matrix.i = const_cast<std::int64_t*>(rows);
  st.matrix.nz = nullptr;
  st.matrix.x = values;
  st.matrix.z = nullptr;
  st.matrix.stype = -1;  // lower triangle
  st.matrix.itype = CHOLMOD_LONG;
  st.matrix.xtype = CHOLMOD_REAL;
  st.matrix.dtype = CHOLMOD_DOUBLE;
  st.matrix.sorted = 1;
  st.matrix.packed = 1;
}

void CholmodSession::set_ordering(Ordering ordering) {
  cholmod_common& common = state_->common;
  switch (ordering) {
    case Ordering::kAmd:
      common.nmethods = 1;
      common.method[0].ordering = CHOLMOD_AMD;
      break;
    case Ordering::kMetis:
      common.nmethods = 1;
      common.method[0].ordering = CHOLMOD_METIS;
      break;
    case Ordering::kAuto:
      common.nmethods = 3;  // CHOLMOD keeps the one whose factor needs the fewest flops
      common.method[0].ordering = CHOLMOD_AMD;
      common.method[1].ordering = CHOLMOD_METIS;
      common.method[2].ordering = CHOLMOD_NESDIS;
      break;
  }
}

const char* CholmodSession::chosen_ordering() const {
  const cholmod_common& common = state_->common;
  switch (common.method[common.selected].ordering) {
    case CHOLMOD_AMD:
      return "AMD";
    case CHOLMOD_METIS:
      return "METIS";
    case CHOLMOD_NESDIS:
      return "NESDIS";
    default:
      return "natural";
  }
}

void CholmodSession::analyze(const char* who) {
  State& st = *state_;
  cholmod_l_free_factor(&st.factor, &st.common);
  st.factor = cholmod_l_analyze(&st.matrix, &st.common);
  if (!st.factor) {
    throw Error(std::string(who) + ": CHOLMOD symbolic analysis failed (status " +
                std::to_string(st.common.status) + ")");
  }
}

bool CholmodSession::factorize() {
  State& st = *state_;
  int ok = 0;
  {
    const SerialOpenMp serial;  // CHOLMOD's OpenMP regions single-threaded for this call
    ok = cholmod_l_factorize(&st.matrix, st.factor, &st.common);
  }
  return ok && st.common.status == CHOLMOD_OK && st.factor->minor == st.matrix.nrow;
}

void CholmodSession::solve(const double* rhs, double* x, const char* who) {
  State& st = *state_;
  const std::size_t n = st.matrix.nrow;
  if (!st.dense_rhs) {
    st.dense_rhs = cholmod_l_zeros(n, 1, CHOLMOD_REAL, &st.common);
    if (!st.dense_rhs)
      throw Error(std::string(who) + ": CHOLMOD could not allocate the right-hand side");
  }
  std::copy_n(rhs, n, static_cast<double*>(st.dense_rhs->x));
  if (!cholmod_l_solve2(CHOLMOD_A, st.factor, st.dense_rhs, nullptr, &st.dense_x, nullptr,
                        &st.dense_y, &st.dense_e, &st.common)) {
    throw Error(std::string(who) + ": CHOLMOD solve failed (status " +
                std::to_string(st.common.status) + ")");
  }
  std::copy_n(static_cast<const double*>(st.dense_x->x), n, x);
}

}  // namespace carat::internal
