#pragma once

/// A residual block from a functor on doubles that cannot be templated (it calls a library, a
/// table, a simulator): the tangent Jacobian is taken by central differences through each
/// variable's manifold, r(x [+] h e_j) - r(x [-] h e_j) over 2h, with h = 1e-6 max(1, |x|_inf)
/// per variable. The functor has the signature
///   bool operator()(const Data&, const double* x0, ..., double* residuals) const
/// and is called 2 D + 1 times per group (D the total tangent dimension). Otherwise it behaves
/// as AutoDiffBlock (rows in groups, any subset, extraction of the selected data).

#include <array>
#include <cmath>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "carat/solver/autodiff_block.hpp"
#include "carat/solver/grouped_rows_block.hpp"
#include "carat/solver/manifold.hpp"

namespace carat {

/// A numerically differentiated block: kGroupRows rows per datum over `Variables...`.
template <typename Functor, typename Data, int kGroupRows, typename... Variables>
class NumericDiffBlock final : public GroupedRowsBlock<Data, kGroupRows> {
  using Base = GroupedRowsBlock<Data, kGroupRows>;
  static_assert(sizeof...(Variables) >= 1, "a block has at least one variable");

 public:
  /// Total tangent dimension D.
  static constexpr int kTangentDim = (Variables::tangent + ...);

  /// The block over `data`; manifolds and errors as for AutoDiffBlock.
  NumericDiffBlock(Functor functor, std::vector<Data> data,
                   std::array<std::shared_ptr<const Manifold>, sizeof...(Variables)> manifolds = {},
                   std::string name = "NumericDiffBlock")
      : NumericDiffBlock(std::move(functor),
                         std::make_shared<const std::vector<Data>>(std::move(data)),
                         std::move(manifolds), std::move(name), {}) {}

  const Manifold* jacobian_manifold(int i) const override {
    return i >= 0 && static_cast<std::size_t>(i) < manifolds_.size()
               ? manifolds_[static_cast<std::size_t>(i)].get()
               : nullptr;
  }

 private:
  static constexpr std::array<int, sizeof...(Variables)> kAmbient{Variables::ambient...};
  static constexpr std::array<int, sizeof...(Variables)> kTangent{Variables::tangent...};

  NumericDiffBlock(Functor functor, std::shared_ptr<const std::vector<Data>> data,
                   std::array<std::shared_ptr<const Manifold>, sizeof...(Variables)> manifolds,
                   std::string name, std::vector<std::uint32_t> row_map)
      : Base(std::move(data), std::vector<int>{Variables::tangent...}, std::move(name),
             std::move(row_map)),
        functor_(std::move(functor)),
        manifolds_(std::move(manifolds)) {
    const std::array<std::shared_ptr<const Manifold>, sizeof...(Variables)> defaults{
        default_manifold<Variables>()...};
    for (std::size_t i = 0; i < manifolds_.size(); ++i) {
      if (!manifolds_[i]) manifolds_[i] = defaults[i];
      if (!manifolds_[i]) {
        throw Error(this->name_ + ": variable " + std::to_string(i) + " needs a manifold");
      }
      if (manifolds_[i]->ambient_size() != kAmbient[i] ||
          manifolds_[i]->tangent_size() != kTangent[i]) {
        throw Error(this->name_ + ": variable " + std::to_string(i) +
                    " is declared with sizes that differ from its manifold " +
                    manifolds_[i]->name());
      }
    }
  }

  /// The variables at x and at x [+/-] h e_j for every tangent direction j.
  struct Perturbed final : Base::Context {
    std::vector<std::vector<double>> center;             // per variable
    std::vector<std::vector<double>> forward, backward;  // per direction: that variable moved
    std::vector<int> variable;                           // per direction: which variable
    std::vector<double> step;                            // per direction: h
  };

  std::unique_ptr<typename Base::Context> prepare(ParameterPointers params) const override {
    if (params.size() != sizeof...(Variables)) {
      throw Error(this->name_ + ": " + std::to_string(params.size()) + " variables given, " +
                  std::to_string(sizeof...(Variables)) + " expected");
    }
    auto out = std::make_unique<Perturbed>();
    for (std::size_t i = 0; i < sizeof...(Variables); ++i) {
      out->center.emplace_back(params[i], params[i] + kAmbient[i]);
    }
    for (std::size_t i = 0; i < sizeof...(Variables); ++i) {
      double scale = 1.0;
      for (int k = 0; k < kAmbient[i]; ++k) scale = std::max(scale, std::abs(params[i][k]));
      const double h = 1e-6 * scale;
      std::vector<double> delta(static_cast<std::size_t>(kTangent[i]), 0.0);
      for (int j = 0; j < kTangent[i]; ++j) {
        std::vector<double> plus(static_cast<std::size_t>(kAmbient[i]));
        std::vector<double> minus(static_cast<std::size_t>(kAmbient[i]));
        delta[static_cast<std::size_t>(j)] = h;
        manifolds_[i]->plus(params[i], delta.data(), plus.data());
        delta[static_cast<std::size_t>(j)] = -h;
        manifolds_[i]->plus(params[i], delta.data(), minus.data());
        delta[static_cast<std::size_t>(j)] = 0.0;
        out->forward.push_back(std::move(plus));
        out->backward.push_back(std::move(minus));
        out->variable.push_back(static_cast<int>(i));
        out->step.push_back(h);
      }
    }
    return out;
  }

  template <std::size_t... I>
  bool call(const std::vector<const double*>& x, const Data& datum, double* residuals,
            std::index_sequence<I...>) const {
    return functor_(datum, x[I]..., residuals);
  }

  bool evaluate_group(const typename Base::Context& context, const Data& datum, double* residuals,
                      double* jacobian) const override {
    const auto& p = static_cast<const Perturbed&>(context);
    std::vector<const double*> x;
    for (const auto& c : p.center) x.push_back(c.data());
    const auto sequence = std::index_sequence_for<Variables...>{};
    if (!call(x, datum, residuals, sequence)) return false;
    if (!jacobian) return true;
    std::array<double, kGroupRows> forward{}, backward{};
    for (std::size_t j = 0; j < p.step.size(); ++j) {
      const auto v = static_cast<std::size_t>(p.variable[j]);
      x[v] = p.forward[j].data();
      if (!call(x, datum, forward.data(), sequence)) return false;
      x[v] = p.backward[j].data();
      if (!call(x, datum, backward.data(), sequence)) return false;
      x[v] = p.center[v].data();
      for (int k = 0; k < kGroupRows; ++k) {
        jacobian[k * kTangentDim + static_cast<int>(j)] =
            (forward[static_cast<std::size_t>(k)] - backward[static_cast<std::size_t>(k)]) /
            (2.0 * p.step[j]);
      }
    }
    return true;
  }

  std::unique_ptr<ResidualBlock> clone_with(std::shared_ptr<const std::vector<Data>> data,
                                            std::vector<std::uint32_t> row_map) const override {
    return std::unique_ptr<ResidualBlock>(new NumericDiffBlock(
        functor_, std::move(data), manifolds_, this->name_, std::move(row_map)));
  }

  Functor functor_;
  std::array<std::shared_ptr<const Manifold>, sizeof...(Variables)> manifolds_;
};

/// A NumericDiffBlock over `data`: make_numeric_diff_block<kGroupRows, Variables...>(f, data).
template <int kGroupRows, typename... Variables, typename Functor, typename Data>
std::shared_ptr<NumericDiffBlock<Functor, Data, kGroupRows, Variables...>> make_numeric_diff_block(
    Functor functor, std::vector<Data> data,
    std::array<std::shared_ptr<const Manifold>, sizeof...(Variables)> manifolds = {},
    std::string name = "NumericDiffBlock") {
  return std::make_shared<NumericDiffBlock<Functor, Data, kGroupRows, Variables...>>(
      std::move(functor), std::move(data), std::move(manifolds), std::move(name));
}

}  // namespace carat
