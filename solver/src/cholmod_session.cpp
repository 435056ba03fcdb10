#include "cholmod_session.hpp"

#include <cholmod.h>

#include <algorithm>
#include <cstdint>
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
  const char* chosen = "natural";  // the ordering analyze_pattern() kept

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

namespace {

/// CHOLMOD's name for an ordering method.
const char* ordering_name(int method) {
  switch (method) {
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

/// Nonzeros of the triangle of a packed pattern that CHOLMOD reads (stype > 0: the upper one,
/// stype < 0: the lower one), diagonal included.
double triangle_nonzeros(const cholmod_sparse& A) {
  const auto* p = static_cast<const std::int64_t*>(A.p);
  const auto* i = static_cast<const std::int64_t*>(A.i);
  std::size_t count = 0;
  for (std::size_t j = 0; j < A.ncol; ++j) {
    for (std::int64_t k = p[j]; k < p[j + 1]; ++k) {
      const auto row = static_cast<std::size_t>(i[k]);
      if (A.stype > 0 ? row <= j : row >= j) ++count;
    }
  }
  return static_cast<double>(count);
}

/// Throws carat::Error ("`who`: CHOLMOD symbolic analysis failed ...") if the analysis gave no
/// factor.
void require_factor(const cholmod_factor* factor, const cholmod_common& common, const char* who) {
  if (!factor) {
    throw Error(std::string(who) + ": CHOLMOD symbolic analysis failed (status " +
                std::to_string(common.status) + ")");
  }
}

}  // namespace

cholmod_factor* CholmodSession::analyze_pattern(cholmod_sparse* A, Ordering ordering) {
  cholmod_common& common = state_->common;
  common.nmethods = 1;
  common.method[0].ordering = ordering == Ordering::kMetis ? CHOLMOD_METIS : CHOLMOD_AMD;
  cholmod_factor* first = cholmod_l_analyze(A, &common);
  state_->chosen = ordering_name(common.method[0].ordering);
  if (!first || ordering != Ordering::kAuto ||
      common.lnz < kNestedDissectionFill * triangle_nonzeros(*A)) {
    return first;
  }
  const double amd_fl = common.fl;
  const double amd_lnz = common.lnz;
  common.nmethods = 2;  // CHOLMOD keeps the one of the two whose factor needs fewer flops
  common.method[0].ordering = CHOLMOD_METIS;
  common.method[1].ordering = CHOLMOD_NESDIS;
  cholmod_factor* dissected = cholmod_l_analyze(A, &common);
  if (dissected && common.fl < amd_fl) {
    state_->chosen = ordering_name(common.method[common.selected].ordering);
    cholmod_l_free_factor(&first, &common);
    return dissected;
  }
  // AMD stays (also when the nested dissections could not be computed).
  cholmod_l_free_factor(&dissected, &common);
  common.status = CHOLMOD_OK;
  common.fl = amd_fl;
  common.lnz = amd_lnz;
  return first;
}

const char* CholmodSession::chosen_ordering() const { return state_->chosen; }

void CholmodSession::analyze(const char* who) {
  State& st = *state_;
  cholmod_l_free_factor(&st.factor, &st.common);
  st.factor = cholmod_l_analyze(&st.matrix, &st.common);
  require_factor(st.factor, st.common, who);
}

void CholmodSession::analyze(const char* who, Ordering ordering) {
  State& st = *state_;
  cholmod_l_free_factor(&st.factor, &st.common);
  st.factor = analyze_pattern(&st.matrix, ordering);
  require_factor(st.factor, st.common, who);
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
