#include "carat/solver/covariance.hpp"

#include <tbb/info.h>
#include <tbb/task_arena.h>

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include "block_evaluator.hpp"
#include "block_variables.hpp"
#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"
#include "free_directions.hpp"
#include "linear_system.hpp"
#include "schur_system.hpp"
#include "serial_openmp.hpp"
#include "sparse_system.hpp"
#include "symmetric_matrix_system.hpp"
#include "system_inverse.hpp"

namespace carat {
namespace {

std::size_t at(int k) { return static_cast<std::size_t>(k); }

/// Damping that holds a coordinate fixed: added to its diagonal it makes the coordinate's
/// coupling to the others vanish below rounding, so the factorization is of H with that row and
/// column removed (and G(c, c) about 1e-16 / H(c, c)).
constexpr double kHoldFixed = 1e16;

/// "variables 3, 4, 9 (3 in all)", at most 8 listed.
std::string list_variables(const std::vector<int>& ids) {
  std::string out = ids.size() == 1 ? "variable " : "variables ";
  for (std::size_t k = 0; k < ids.size() && k < 8; ++k) {
    if (k > 0) out += ", ";
    out += std::to_string(ids[k]);
  }
  if (ids.size() > 8) out += ", ... (" + std::to_string(ids.size()) + " in all)";
  return out;
}

/// Throws unless every free variable is touched by a residual block.
void check_touched(const Problem& problem) {
  std::vector<char> touched(at(problem.num_variables()), 0);
  internal::for_each_block_variables(problem, [&](std::span<const VariableId> variables) {
    for (VariableId v : variables) touched[at(v.index)] = 1;
  });
  std::vector<int> untouched;
  for (int v = 0; v < problem.num_variables(); ++v) {
    if (!touched[at(v)] && !problem.is_constant(VariableId{v})) untouched.push_back(v);
  }
  if (!untouched.empty()) {
    throw Error("covariance: " + list_variables(untouched) +
                (untouched.size() == 1 ? " is" : " are") +
                " free but touched by no residual block: nothing constrains " +
                (untouched.size() == 1 ? "it" : "them") + " (hold constant or remove)");
  }
}

}  // namespace

const char* to_string(CovarianceGauge gauge) {
  return gauge == CovarianceGauge::kError ? "error" : "pseudo-inverse";
}

CovarianceGauge parse_covariance_gauge(std::string_view name) {
  if (name == "error") return CovarianceGauge::kError;
  if (name == "pseudo-inverse") return CovarianceGauge::kPseudoInverse;
  throw Error("unknown covariance gauge " + quote_bytes(name) + " (valid: error, pseudo-inverse)");
}

struct Covariance::Impl {
  std::unique_ptr<internal::LinearSystem> system;
  internal::SchurSystem* schur = nullptr;  // the system, when it is the Schur complement
  /// The Schur complement S as a matrix of its own (formed once by the Schur system), where the
  /// free directions of a singular S are searched and removed.
  std::unique_ptr<internal::SymmetricMatrixSystem> reduced;
  std::optional<internal::SystemInverse> inverse;
  std::vector<int> offset;  // per variable: system offset, -1 when constant
  std::vector<int> dim;     // per variable: tangent size
  // Free directions (orthonormal), over the kept coordinates (all of them without a Schur
  // complement; an eliminated variable's rows are lifted from these): kept size x k.
  Eigen::MatrixXd N;
  CovarianceTimes time;

  void compute(const Problem& problem, const Options& options);
  void check_eliminated(double max_variance_inflation) const;
  /// The largest H(j, j) G(j, j).
  double largest_inflation(const Eigen::VectorXd& diagonal) const;
  int variable_at(int system_offset) const;
  /// Rows a0 .. a0 + da of X (kept rows; an eliminated variable's lifted).
  Eigen::MatrixXd rows(const Eigen::MatrixXd& X, int a0, int da) const;
  [[noreturn]] void throw_singular(const Eigen::VectorXd& scale) const;
  void remove_free_directions(internal::LinearSystem& target, const Eigen::VectorXd& diagonal,
                              const Eigen::VectorXd& scale, double max_variance_inflation);
  void make_inverse(internal::LinearSystem& target);
  int check(VariableId id) const;
};

int Covariance::Impl::variable_at(int system_offset) const {
  for (std::size_t v = 0; v < offset.size(); ++v) {
    if (offset[v] >= 0 && system_offset >= offset[v] && system_offset < offset[v] + dim[v]) {
      return static_cast<int>(v);
    }
  }
  return -1;
}

void Covariance::Impl::make_inverse(internal::LinearSystem& target) {
  if (schur) {
    inverse.emplace(*schur, &target == schur ? schur->reduced_cholmod() : reduced->cholmod());
  } else {
    inverse.emplace(static_cast<internal::SparseSystem&>(target));
  }
}

Eigen::MatrixXd Covariance::Impl::rows(const Eigen::MatrixXd& X, int a0, int da) const {
  if (a0 < X.rows()) return X.middleRows(a0, da);
  return internal::lift_eliminated(*schur, schur->eliminated_at(a0), X);
}

void Covariance::Impl::check_eliminated(double max_variance_inflation) const {
  // Each eliminated variable's own V must be nonsingular: S is formed through V^-1.
  std::vector<int> singular;
  for (int p = 0; p < schur->num_eliminated(); ++p) {
    const auto pp = at(p);
    const int dp = schur->eliminated_dim(pp);
    const Eigen::Map<const Eigen::MatrixXd> V(schur->eliminated_v(pp), dp, dp);
    const Eigen::LLT<Eigen::MatrixXd> llt(V);
    bool ok = llt.info() == Eigen::Success;
    if (ok) {
      const Eigen::MatrixXd V_inverse = llt.solve(Eigen::MatrixXd::Identity(dp, dp));
      for (int j = 0; j < dp && ok; ++j) ok = V(j, j) * V_inverse(j, j) <= max_variance_inflation;
    }
    if (!ok) singular.push_back(variable_at(schur->eliminated_offset(pp)));
  }
  if (!singular.empty()) {
    throw Error("covariance: " + list_variables(singular) +
                (singular.size() == 1 ? " is" : " are") + " eliminated but not determined by " +
                (singular.size() == 1 ? "its" : "their") +
                " own blocks alone (a singular V, e.g. a point seen along one ray): no "
                "covariance (remove, or solve the whole system: LinearSolver::kCholesky)");
  }
}

double Covariance::Impl::largest_inflation(const Eigen::VectorXd& diagonal) const {
  const Eigen::VectorXd g = inverse->diagonal_bound();
  double worst = 0.0;
  for (int j = 0; j < g.size(); ++j) {
    const double inflation = diagonal[j] * g[j];
    // NaN (a factor that overflowed) counts as infinitely inflated.
    if (!(inflation <= worst)) worst = std::isnan(inflation) ? HUGE_VAL : inflation;
  }
  return worst;
}

void Covariance::Impl::throw_singular(const Eigen::VectorXd& scale) const {
  // The variables the free directions move: those with a coordinate whose (diag(H)-scaled)
  // share of the free directions is above 1e-6 of the largest.
  const int n = system->size();
  Eigen::VectorXd share(n);
  for (std::size_t v = 0; v < offset.size(); ++v) {
    if (offset[v] < 0) continue;
    share.segment(offset[v], dim[v]) =
        (scale.segment(offset[v], dim[v]).cwiseSqrt().asDiagonal() * rows(N, offset[v], dim[v]))
            .rowwise()
            .norm();
  }
  const double largest = n > 0 ? share.maxCoeff() : 0.0;
  std::vector<int> moved;
  for (std::size_t v = 0; v < offset.size(); ++v) {
    if (offset[v] < 0) continue;
    if (share.segment(offset[v], dim[v]).maxCoeff() > 1e-6 * largest) {
      moved.push_back(static_cast<int>(v));
    }
  }
  throw Error("covariance: H is singular: " + std::to_string(N.cols()) + " free direction" +
              (N.cols() == 1 ? "" : "s") + " (a gauge freedom or an unobservable direction) move " +
              list_variables(moved) +
              "; hold a variable constant, add a prior, or ask for the pseudo-inverse gauge");
}

void Covariance::Impl::remove_free_directions(internal::LinearSystem& target,
                                              const Eigen::VectorXd& diagonal,
                                              const Eigen::VectorXd& scale,
                                              double max_variance_inflation) {
  // G: the inverse with k of target's coordinates held fixed, chosen (column-pivoted QR of the
  // scaled free directions) so that the rest of it is nonsingular; then P G P^T with
  // P = I - N N^T over the kept coordinates (see SystemInverse::remove_free_directions()).
  const Eigen::Index k = N.cols();
  const int m = target.size();
  const Eigen::MatrixXd scaled = (scale.head(m).cwiseSqrt().asDiagonal() * N).transpose();
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(scaled);
  Eigen::VectorXd damping = Eigen::VectorXd::Zero(m);
  std::vector<char> held(at(system->size()), 0);
  for (Eigen::Index c = 0; c < k; ++c) {
    const Eigen::Index j = qr.colsPermutation().indices()[c];
    damping[j] = kHoldFixed * scale[j];
    held[static_cast<std::size_t>(j)] = 1;
  }
  if (!target.factorize(damping)) {
    throw Error("covariance: H is singular and holding " + std::to_string(k) +
                " coordinates fixed did not make the rest of it positive definite");
  }
  make_inverse(target);
  const Eigen::VectorXd g = inverse->diagonal_bound();
  for (int j = 0; j < g.size(); ++j) {
    if (held[at(j)]) continue;
    if (!(diagonal[j] * g[j] <= max_variance_inflation)) {
      throw Error("covariance: H is singular and its " + std::to_string(k) +
                  " free directions found do not account for all of it (variable " +
                  std::to_string(variable_at(j)) + " is still free)");
    }
  }
  Eigen::MatrixXd Q(m, k);
  Eigen::VectorXd x;
  for (Eigen::Index c = 0; c < k; ++c) {
    target.solve(N.col(c), &x);
    Q.col(c) = x;
  }
  Eigen::MatrixXd K = N.transpose() * Q;
  K = 0.5 * (K + K.transpose()).eval();
  inverse->remove_free_directions(N, std::move(Q), std::move(K));
}

void Covariance::Impl::compute(const Problem& problem, const Options& options) {
  const Stopwatch total;
  if (!(options.max_variance_inflation > 1.0) || !std::isfinite(options.max_variance_inflation)) {
    throw Error("covariance: max_variance_inflation must be finite and > 1");
  }
  if (options.num_threads < 1) throw Error("covariance: num_threads must be >= 1");
  check_touched(problem);

  Stopwatch stage;
  SolverOptions solver_options;
  solver_options.linear_solver = options.linear_solver;
  solver_options.ordering = options.ordering;
  solver_options.num_threads = options.num_threads;
  system = internal::make_linear_system(problem, solver_options);
  schur = dynamic_cast<internal::SchurSystem*>(system.get());
  time.factorize_s += stage.elapsed_s();
  offset = system->variable_offset();
  for (int v = 0; v < problem.num_variables(); ++v) {
    dim.push_back(problem.manifold(VariableId{v}).tangent_size());
  }
  const int n = system->size();

  internal::BlockEvaluator evaluator(problem);
  const std::vector<double> values(problem.all_values().begin(), problem.all_values().end());
  evaluator.bind(0, values.data());
  Eigen::VectorXd gradient;
  const internal::LinearizeReport linearized = system->linearize(evaluator, 0, &gradient);
  time.linearize_s += linearized.time.linearize_s + linearized.time.assembly_s;
  if (!linearized.ok) throw Error("covariance: " + linearized.error);
  if (n == 0) {
    time.total_s = total.elapsed_s();
    return;
  }

  const Eigen::VectorXd diagonal = system->diagonal();
  const Eigen::VectorXd scale = diagonal.unaryExpr([](double d) { return d > 0.0 ? d : 1.0; });
  if (schur) check_eliminated(options.max_variance_inflation);
  stage.restart();
  const bool factorized = system->factorize(Eigen::VectorXd::Zero(n));
  time.factorize_s += stage.restart();
  bool singular = !factorized;
  if (factorized) {
    make_inverse(*system);
    singular = largest_inflation(diagonal) > options.max_variance_inflation;
  }
  if (singular) {
    inverse.reset();
    // With the Schur complement (every V nonsingular, checked above) the free directions are
    // S's: searched and removed on S alone, then lifted to the eliminated variables.
    internal::LinearSystem* target = system.get();
    if (schur) {
      reduced = std::make_unique<internal::SymmetricMatrixSystem>(
          schur->reduced_size(), schur->reduced_colptr(), schur->reduced_rows(),
          schur->reduced_values());
      target = reduced.get();
    }
    N = internal::free_directions(*target, scale.head(target->size()),
                                  options.max_variance_inflation);
    if (N.cols() == 0) {
      throw Error(
          "covariance: H is singular (its factorization failed or a variance was inflated "
          "beyond max_variance_inflation), but no free direction was found");
    }
    if (options.gauge == CovarianceGauge::kError) throw_singular(scale);
    remove_free_directions(*target, diagonal, scale, options.max_variance_inflation);
  }
  time.inverse_s += stage.elapsed_s();
  time.total_s = total.elapsed_s();
}

int Covariance::Impl::check(VariableId id) const {
  if (id.index < 0 || at(id.index) >= offset.size()) {
    throw Error("covariance: variable " + std::to_string(id.index) + " is not in the problem");
  }
  const int o = offset[at(id.index)];
  if (o < 0) {
    throw Error("covariance: variable " + std::to_string(id.index) +
                " is constant: it has no covariance");
  }
  return o;
}

Covariance::Covariance(const Problem& problem) : Covariance(problem, Options{}) {}

Covariance::Covariance(const Problem& problem, const Options& options)
    : impl_(std::make_unique<Impl>()) {
  tbb::task_arena arena(std::clamp(options.num_threads, 1, tbb::info::default_concurrency()));
  const internal::SerialOpenMp serial;  // Eigen's large products (null space) on this thread
  arena.execute([&] { impl_->compute(problem, options); });
}

Covariance::~Covariance() = default;
Covariance::Covariance(Covariance&&) noexcept = default;
Covariance& Covariance::operator=(Covariance&&) noexcept = default;

Eigen::MatrixXd Covariance::block(VariableId id) const { return block(id, id); }

Eigen::MatrixXd Covariance::block(VariableId a, VariableId b) const {
  Impl& m = *impl_;
  const int a0 = m.check(a);
  const int b0 = m.check(b);
  const int da = m.dim[at(a.index)];
  const int db = m.dim[at(b.index)];
  Eigen::MatrixXd out = m.inverse->block(a0, da, b0, db);
  if (a == b) out = 0.5 * (out + out.transpose()).eval();
  return out;
}

std::vector<Eigen::MatrixXd> Covariance::blocks(std::span<const VariableId> ids) const {
  std::vector<Eigen::MatrixXd> out;
  out.reserve(ids.size());
  for (const VariableId id : ids) {
    if (id.index >= 0 && at(id.index) < impl_->offset.size() && impl_->offset[at(id.index)] < 0) {
      out.emplace_back();
    } else {
      out.push_back(block(id));
    }
  }
  return out;
}

bool Covariance::on_pattern(VariableId a, VariableId b) const {
  const Impl& m = *impl_;
  if (a.index < 0 || b.index < 0 || at(a.index) >= m.offset.size() ||
      at(b.index) >= m.offset.size()) {
    return false;
  }
  const int a0 = m.offset[at(a.index)];
  const int b0 = m.offset[at(b.index)];
  if (a0 < 0 || b0 < 0) return false;
  return m.inverse->on_pattern(a0, b0);
}

int Covariance::gauge_dimension() const { return static_cast<int>(impl_->N.cols()); }

int Covariance::size() const { return impl_->system ? impl_->system->size() : 0; }

const CovarianceTimes& Covariance::time() const { return impl_->time; }

const std::string& Covariance::description() const { return impl_->system->description(); }

}  // namespace carat
