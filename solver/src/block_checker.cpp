#include "carat/solver/block_checker.hpp"

#include <cxxabi.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <functional>
#include <limits>
#include <memory>
#include <numeric>
#include <random>
#include <set>
#include <typeinfo>

#include "carat/base/error.hpp"

namespace carat {
namespace {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// A value no block computes by chance: a NaN with a payload.
double sentinel() {
  const std::uint64_t bits = 0x7ff8dead0000beefULL;
  double value;
  std::memcpy(&value, &bits, sizeof(value));
  return value;
}

bool is_sentinel(double value) {
  std::uint64_t bits;
  std::memcpy(&bits, &value, sizeof(value));
  return bits == 0x7ff8dead0000beefULL;
}

std::string number(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.3e", value);
  return buffer;
}

/// max |a - b| / max(1e-300, max |b|) over two arrays.
double relative_difference(const double* a, const double* b, std::size_t n) {
  double diff = 0.0, scale = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    diff = std::max(diff, std::abs(a[i] - b[i]));
    scale = std::max(scale, std::abs(b[i]));
  }
  if (!(diff == diff)) return std::numeric_limits<double>::infinity();
  return diff / std::max(scale, 1e-300);
}

/// Residuals and reduced Jacobian rows of `rows`.
void evaluate(const ResidualBlock& block, ParameterPointers params, std::span<const int> rows,
              Eigen::VectorXd* residuals, RowMatrix* jacobian) {
  residuals->resize(static_cast<Eigen::Index>(rows.size()));
  jacobian->resize(static_cast<Eigen::Index>(rows.size()), block.reduced_dim());
  block.evaluate_rows(params, rows, residuals->data(), jacobian->data());
}

/// A readable name of a block's dynamic type.
std::string type_name(const ResidualBlock& block) {
  const char* mangled = typeid(block).name();
  int status = 0;
  char* demangled = abi::__cxa_demangle(mangled, nullptr, nullptr, &status);
  std::string out = status == 0 && demangled ? demangled : mangled;
  std::free(demangled);
  if (out.size() > 120) out = out.substr(0, 117) + "...";
  return out;
}

}  // namespace

std::string ProblemCheckReport::summary() const {
  if (ok) return "ok (" + std::to_string(checked_blocks) + " block types checked)";
  std::string out;
  for (const std::string& f : failures) out += (out.empty() ? "" : "\n") + f;
  return out;
}

ProblemCheckReport check_problem(const Problem& problem, const BlockCheckOptions& options) {
  ProblemCheckReport report;
  std::set<std::string> seen;
  const auto blocks = problem.blocks();
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    const ResidualBlock& block = *blocks[i].block;
    if (!seen.insert(typeid(block).name()).second) continue;
    ++report.checked_blocks;
    std::vector<const Manifold*> manifolds;
    std::vector<const double*> params;
    for (VariableId v : blocks[i].variables) {
      manifolds.push_back(&problem.manifold(v));
      params.push_back(problem.value(v).data());
    }
    BlockCheckReport one;
    try {
      one = check_residual_block(block, manifolds, params, options);
    } catch (const std::exception& e) {
      one.failures.push_back(e.what());
    }
    if (one.failures.empty()) continue;
    report.ok = false;
    report.failures.push_back("residual block " + std::to_string(i) +
                              (block.name().empty() ? std::string() : " ('" + block.name() + "')") +
                              ", of type " + type_name(block) +
                              ", breaks the block contract: " + one.summary());
  }
  return report;
}

std::string BlockCheckReport::summary() const {
  if (ok) return "ok";
  std::string out;
  for (const std::string& f : failures) out += (out.empty() ? "" : "; ") + f;
  return out;
}

BlockCheckReport check_residual_block(const ResidualBlock& block,
                                      std::span<const Manifold* const> manifolds,
                                      ParameterPointers params, const BlockCheckOptions& options) {
  BlockCheckReport report;
  // A copy: a span over a temporary (one of the faults looked for) dangles after the next call.
  const std::span<const int> first_dims = block.tangent_dims();
  const std::vector<int> dims(first_dims.begin(), first_dims.end());
  if (manifolds.size() != dims.size() || params.size() != dims.size()) {
    throw Error("check_residual_block: the block has " + std::to_string(dims.size()) +
                " variables but " + std::to_string(manifolds.size()) + " manifolds and " +
                std::to_string(params.size()) + " parameter pointers were given");
  }
  const auto fail = [&](const std::string& what) { report.failures.push_back(what); };
  const auto guarded = [&](const char* check, const std::function<void()>& f) {
    try {
      f();
    } catch (const std::exception& e) {
      fail(std::string(check) + ": threw: " + e.what());
    }
  };

  // tangent_dims(): one span, stable, matching the manifolds.
  const auto again = block.tangent_dims();
  if (again.data() != first_dims.data() || again.size() != dims.size() ||
      !std::equal(dims.begin(), dims.end(), again.begin())) {
    fail("tangent_dims() returns a different span on each call (a span over a temporary?)");
  }
  for (std::size_t v = 0; v < dims.size(); ++v) {
    if (dims[v] != manifolds[v]->tangent_size()) {
      fail("tangent_dims()[" + std::to_string(v) + "] is " + std::to_string(dims[v]) +
           " but the manifold " + manifolds[v]->name() + " has " +
           std::to_string(manifolds[v]->tangent_size()));
    }
  }
  const int n = block.num_rows();
  const int r = block.reduced_dim();
  if (n < 1) fail("num_rows() is " + std::to_string(n) + " (at least 1 is needed)");
  if (r < 1) fail("reduced_dim() is " + std::to_string(r));
  if (!report.failures.empty()) return report;

  // evaluate_rows() honours `rows`: one row asked, one row written (into buffers of N + 1 rows).
  guarded("honouring rows", [&] {
    for (int asked : {0, n - 1}) {
      std::vector<double> residuals(static_cast<std::size_t>(n) + 1, sentinel());
      std::vector<double> jacobian((static_cast<std::size_t>(n) + 1) * r, sentinel());
      const int rows[1] = {asked};
      block.evaluate_rows(params, rows, residuals.data(), jacobian.data());
      const auto written_residuals = static_cast<std::size_t>(std::count_if(
          residuals.begin() + 1, residuals.end(), [](double x) { return !is_sentinel(x); }));
      const auto written_jacobian = static_cast<std::size_t>(std::count_if(
          jacobian.begin() + r, jacobian.end(), [](double x) { return !is_sentinel(x); }));
      if (written_residuals > 0 || written_jacobian > 0) {
        fail("evaluate_rows() asked for row " + std::to_string(asked) + " wrote " +
             std::to_string(written_residuals) + " more residuals and " +
             std::to_string(written_jacobian) +
             " more Jacobian entries (it must write only the rows in `rows`)");
        return;
      }
    }
  });

  // Later checks hand evaluate_rows() buffers sized for the rows asked: a block that writes
  // more would overflow them.
  if (!report.failures.empty()) return report;

  // The Jacobian against central differences: of the plain rows when the block weights each
  // group by its loss (the weights depend on the point; the rows' Jacobians are taken at it).
  guarded("Jacobian", [&] {
    std::unique_ptr<ResidualBlock> plain;
    if (block.group_loss()) {
      std::vector<int> every(static_cast<std::size_t>(n));
      std::iota(every.begin(), every.end(), 0);
      std::vector<double> loss_weights(every.size());
      plain = block.extract_rows_without_loss(params, every, loss_weights.data());
      if (!plain) {
        fail("the block has a group loss but extract_rows_without_loss() returned null");
        return;
      }
    }
    report.jacobian = check_jacobians(plain ? *plain : block, manifolds, params, options.jacobian);
    if (!report.jacobian.ok) fail("Jacobian: " + report.jacobian.message);
  });

  std::vector<int> all(static_cast<std::size_t>(n));
  std::iota(all.begin(), all.end(), 0);
  Eigen::VectorXd full_residuals;
  RowMatrix full_jacobian;
  guarded("full evaluation",
          [&] { evaluate(block, params, all, &full_residuals, &full_jacobian); });
  if (full_residuals.size() != n) return report;  // the failure is recorded

  // Subsets in any order, with repeats.
  std::mt19937 rng(options.seed);
  std::uniform_int_distribution<int> pick(0, n - 1);
  std::vector<int> subset(static_cast<std::size_t>(std::max(1, options.subset_rows)));
  for (int& row : subset) row = pick(rng);
  subset.front() = n - 1;
  if (subset.size() > 2) subset[1] = subset[2];  // a repeat, next to each other
  guarded("subsets", [&] {
    Eigen::VectorXd residuals;
    RowMatrix jacobian;
    evaluate(block, params, subset, &residuals, &jacobian);
    for (std::size_t k = 0; k < subset.size(); ++k) {
      const auto row = static_cast<Eigen::Index>(subset[k]);
      const double dr =
          relative_difference(&residuals[static_cast<Eigen::Index>(k)], &full_residuals[row], 1);
      const double dj =
          relative_difference(jacobian.row(static_cast<Eigen::Index>(k)).data(),
                              full_jacobian.row(row).data(), static_cast<std::size_t>(r));
      if (dr > options.relative_tolerance &&
          std::abs(residuals[static_cast<Eigen::Index>(k)] - full_residuals[row]) > 1e-300) {
        fail("row " + std::to_string(row) +
             " asked in a subset differs from the full evaluation (" + number(dr) + " relative)");
        return;
      }
      if (dj > options.relative_tolerance) {
        fail("the Jacobian of row " + std::to_string(row) +
             " asked in a subset differs from the full evaluation (" + number(dj) + " relative)");
        return;
      }
    }
  });

  // accumulate() and squared_norm() against the defaults.
  guarded("accumulate", [&] {
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(r, r), H0 = H;
    Eigen::VectorXd b = Eigen::VectorXd::Zero(r), b0 = b;
    const double c = block.accumulate(params, H, b);
    const double c0 = block.ResidualBlock::accumulate(params, H0, b0);
    const double dH = relative_difference(H.data(), H0.data(), static_cast<std::size_t>(H.size()));
    const double db = relative_difference(b.data(), b0.data(), static_cast<std::size_t>(b.size()));
    // With a group loss, c is sum_g rho(s_g), not the rows' squares (checked below).
    const double dc = block.group_loss() ? 0.0 : relative_difference(&c, &c0, 1);
    if (dH > options.relative_tolerance || db > options.relative_tolerance ||
        dc > options.relative_tolerance) {
      fail("accumulate() differs from J_r^T J_r, J_r^T r, r^T r of evaluate_rows() (H " +
           number(dH) + ", b " + number(db) + ", c " + number(dc) + " relative)");
    }
  });
  guarded("squared_norm", [&] {
    const double c = block.squared_norm(params);
    double c0 = full_residuals.squaredNorm() + block.constant_cost();
    if (block.group_loss()) {
      Eigen::MatrixXd H = Eigen::MatrixXd::Zero(r, r);
      Eigen::VectorXd b = Eigen::VectorXd::Zero(r);
      c0 = block.accumulate(params, H, b);
    }
    const double dc = relative_difference(&c, &c0, 1);
    if (dc > options.relative_tolerance) {
      fail("squared_norm() is " + number(c) + " but " +
           (block.group_loss() ? "accumulate() gives c = " : "the rows' squares sum to ") +
           number(c0));
    }
  });

  // Extracts hold exactly the selected rows (and their weights).
  std::vector<int> selected;
  for (int k = n - 1; k >= 0 && selected.size() < 7; k -= std::max(1, n / 7)) selected.push_back(k);
  const auto compare_extract = [&](const ResidualBlock& part, const char* what,
                                   const std::vector<double>* weights) {
    if (part.num_rows() != static_cast<int>(selected.size())) {
      fail(std::string(what) + " has " + std::to_string(part.num_rows()) + " rows, " +
           std::to_string(selected.size()) + " were selected");
      return;
    }
    const auto part_dims = part.tangent_dims();
    if (!std::equal(dims.begin(), dims.end(), part_dims.begin(), part_dims.end()) ||
        part.reduced_dim() != r) {
      fail(std::string(what) + " has other tangent_dims() or reduced_dim()");
      return;
    }
    std::vector<int> rows(selected.size());
    std::iota(rows.begin(), rows.end(), 0);
    Eigen::VectorXd residuals;
    RowMatrix jacobian;
    evaluate(part, params, rows, &residuals, &jacobian);
    for (std::size_t k = 0; k < selected.size(); ++k) {
      const auto row = static_cast<Eigen::Index>(selected[k]);
      const double s = weights ? std::sqrt((*weights)[k]) : 1.0;
      const double expected = s * full_residuals[row];
      const Eigen::VectorXd expected_jacobian = s * full_jacobian.row(row).transpose();
      const double dr = relative_difference(&residuals[static_cast<Eigen::Index>(k)], &expected, 1);
      const double dj = relative_difference(jacobian.row(static_cast<Eigen::Index>(k)).data(),
                                            expected_jacobian.data(), static_cast<std::size_t>(r));
      if ((dr > options.relative_tolerance && std::abs(expected) > 1e-300) ||
          dj > options.relative_tolerance) {
        fail(std::string(what) + ": its row " + std::to_string(k) + " is not " +
             (weights ? "sqrt(w) times " : "") + "row " + std::to_string(row) + " (" + number(dr) +
             ", " + number(dj) + " relative)");
        return;
      }
    }
  };
  guarded("extract_rows", [&] {
    if (const auto part = block.extract_rows(selected))
      compare_extract(*part, "extract_rows()", nullptr);
  });
  guarded("extract_weighted_rows", [&] {
    std::vector<double> weights(selected.size());
    std::uniform_real_distribution<double> weight(0.5, 4.0);
    for (double& w : weights) w = weight(rng);
    if (const auto part = block.extract_weighted_rows(selected, weights)) {
      compare_extract(*part, "extract_weighted_rows()", &weights);
    }
  });
  report.ok = report.failures.empty();
  return report;
}

}  // namespace carat
