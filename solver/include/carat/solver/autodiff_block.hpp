#pragma once

/// A residual block from a functor written once, templated on the scalar, that evaluates the
/// rows of one datum (a group of kGroupRows rows) from the variables' ambient values, in the
/// manner of Ceres's AutoDiffCostFunction:
///
///   struct ExpResidual {  // y = exp(m x + c), one row per (x, y)
///     template <typename T>
///     bool operator()(const Eigen::Vector2d& xy, const T* mc, T* residual) const {
///       residual[0] = xy.y() - exp(mc[0] * xy.x() + mc[1]);
///       return true;
///     }
///   };
///   auto block = make_autodiff_block<1, VariableSize<2>>(ExpResidual{}, observations);
///
/// carat evaluates it with Eigen's AutoDiffScalar (forward-mode dual numbers, shipped with
/// Eigen; derivatives of fixed size D = the sum of the tangent sizes) and reaches the tangent
/// Jacobian (right perturbation) through each variable's manifold: a variable enters as
/// x + P delta with P = Manifold::plus_jacobian(x), built once per evaluation. Any subset of rows
/// can be evaluated, so the block compresses; extract_rows() copies the data of the selected
/// groups only. A functor that returns false makes its rows NaN: the solver rejects a trial step
/// there, and names the block and the row if it happens at the start.

#include <Eigen/Core>
#include <array>
#include <memory>
#include <string>
#include <unsupported/Eigen/AutoDiff>
#include <utility>
#include <vector>

#include "carat/solver/grouped_rows_block.hpp"
#include "carat/solver/manifold.hpp"

namespace carat {

/// Sizes of one variable of a differentiated block: doubles stored and tangent dimension.
template <int kAmbient, int kTangent = kAmbient>
struct VariableSize {
  static_assert(kAmbient >= 1 && kTangent >= 1 && kTangent <= kAmbient, "bad variable sizes");
  static constexpr int ambient = kAmbient;  ///< doubles stored
  static constexpr int tangent = kTangent;  ///< degrees of freedom
};
/// An SE(3) variable: [qx, qy, qz, qw, tx, ty, tz], tangent [omega, v].
using Se3Variable = VariableSize<7, 6>;
/// An SO(3) variable: [qx, qy, qz, qw], tangent omega.
using So3Variable = VariableSize<4, 3>;

/// The manifold carat assumes for a variable of these sizes when none is given: Euclidean when
/// ambient == tangent, SE(3) for 7/6, SO(3) for 4/3; null otherwise (then one must be given).
template <typename Variable>
std::shared_ptr<const Manifold> default_manifold() {
  if constexpr (Variable::ambient == Variable::tangent) {
    return euclidean_manifold(Variable::ambient);
  } else if constexpr (Variable::ambient == 7 && Variable::tangent == 6) {
    return se3_manifold();
  } else if constexpr (Variable::ambient == 4 && Variable::tangent == 3) {
    return so3_manifold();
  } else {
    return nullptr;
  }
}

/// An automatically differentiated block: kGroupRows rows per datum of type Data over the
/// variables `Variables...` (VariableSize types). The functor has the signature
///   template <typename T> bool operator()(const Data&, const T* x0, ..., T* residuals) const
/// with one ambient array per variable and kGroupRows residuals.
template <typename Functor, typename Data, int kGroupRows, typename... Variables>
class AutoDiffBlock final : public GroupedRowsBlock<Data, kGroupRows> {
  using Base = GroupedRowsBlock<Data, kGroupRows>;
  static_assert(sizeof...(Variables) >= 1, "a block has at least one variable");

 public:
  /// Number of variables.
  static constexpr int kNumVariables = sizeof...(Variables);
  /// Total tangent dimension D (the derivative size of the dual numbers).
  static constexpr int kTangentDim = (Variables::tangent + ...);
  /// Total ambient size.
  static constexpr int kAmbientSize = (Variables::ambient + ...);
  /// The dual number type the functor is evaluated with.
  using Dual = Eigen::AutoDiffScalar<Eigen::Matrix<double, kTangentDim, 1>>;

  /// The block over `data` (one group of rows each). `manifolds` may leave entries null for the
  /// defaults (default_manifold()); `name` is used in messages. Throws carat::Error for no data
  /// or a manifold whose sizes differ from the variable's.
  AutoDiffBlock(Functor functor, std::vector<Data> data,
                std::array<std::shared_ptr<const Manifold>, sizeof...(Variables)> manifolds = {},
                std::string name = "AutoDiffBlock")
      : AutoDiffBlock(std::move(functor),
                      std::make_shared<const std::vector<Data>>(std::move(data)),
                      std::move(manifolds), std::move(name), {}) {}

  double accumulate(ParameterPointers params, Eigen::Ref<Eigen::MatrixXd> H_r,
                    Eigen::Ref<Eigen::VectorXd> b_r) const override {
    return this->template accumulate_groups<kTangentDim>(params, H_r, b_r);
  }

 private:
  static constexpr std::array<int, sizeof...(Variables)> kAmbient{Variables::ambient...};
  static constexpr std::array<int, sizeof...(Variables)> kTangent{Variables::tangent...};
  static constexpr std::array<int, sizeof...(Variables)> offsets(
      const std::array<int, sizeof...(Variables)>& sizes) {
    std::array<int, sizeof...(Variables)> out{};
    int sum = 0;
    for (std::size_t i = 0; i < sizes.size(); ++i) {
      out[i] = sum;
      sum += sizes[i];
    }
    return out;
  }
  static constexpr std::array<int, sizeof...(Variables)> kAmbientOffset = offsets(kAmbient);
  static constexpr std::array<int, sizeof...(Variables)> kTangentOffset = offsets(kTangent);

  AutoDiffBlock(Functor functor, std::shared_ptr<const std::vector<Data>> data,
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
        throw Error(this->name_ + ": variable " + std::to_string(i) +
                    " needs a manifold (no default for " + std::to_string(kAmbient[i]) +
                    " stored values with " + std::to_string(kTangent[i]) + " degrees of freedom)");
      }
      if (manifolds_[i]->ambient_size() != kAmbient[i] ||
          manifolds_[i]->tangent_size() != kTangent[i]) {
        throw Error(this->name_ + ": variable " + std::to_string(i) + " is declared with " +
                    std::to_string(kAmbient[i]) + " stored values and " +
                    std::to_string(kTangent[i]) + " degrees of freedom but its manifold " +
                    manifolds_[i]->name() + " has " +
                    std::to_string(manifolds_[i]->ambient_size()) + " and " +
                    std::to_string(manifolds_[i]->tangent_size()));
      }
    }
  }

  struct DualValues final : Base::Context {
    std::array<Dual, kAmbientSize> x;
  };

  std::unique_ptr<typename Base::Context> prepare(ParameterPointers params) const override {
    if (params.size() != sizeof...(Variables)) {
      throw Error(this->name_ + ": " + std::to_string(params.size()) + " variables given, " +
                  std::to_string(sizeof...(Variables)) + " expected");
    }
    auto out = std::make_unique<DualValues>();
    std::array<double, 64> plus{};
    std::vector<double> plus_large;
    for (std::size_t i = 0; i < sizeof...(Variables); ++i) {
      const int a = kAmbient[i], t = kTangent[i];
      double* P = plus.data();
      if (a * t > static_cast<int>(plus.size())) {
        plus_large.resize(static_cast<std::size_t>(a * t));
        P = plus_large.data();
      }
      manifolds_[i]->plus_jacobian(params[i], P);
      for (int k = 0; k < a; ++k) {
        Dual& d = out->x[static_cast<std::size_t>(kAmbientOffset[i] + k)];
        d.value() = params[i][k];
        d.derivatives().setZero();
        for (int j = 0; j < t; ++j) d.derivatives()[kTangentOffset[i] + j] = P[k * t + j];
      }
    }
    return out;
  }

  template <std::size_t... I>
  bool call(const DualValues& values, const Data& datum, Dual* residuals,
            std::index_sequence<I...>) const {
    return functor_(datum, values.x.data() + kAmbientOffset[I]..., residuals);
  }

  bool evaluate_group(const typename Base::Context& context, const Data& datum, double* residuals,
                      double* jacobian) const override {
    const auto& values = static_cast<const DualValues&>(context);
    std::array<Dual, kGroupRows> r;
    for (Dual& d : r) d = Dual(0.0, Eigen::Matrix<double, kTangentDim, 1>::Zero());
    if (!call(values, datum, r.data(), std::index_sequence_for<Variables...>{})) return false;
    for (int k = 0; k < kGroupRows; ++k) {
      residuals[k] = r[static_cast<std::size_t>(k)].value();
      if (jacobian) {
        const auto& g = r[static_cast<std::size_t>(k)].derivatives();
        for (int j = 0; j < kTangentDim; ++j) {
          // A row that does not depend on the variables may keep an empty derivative.
          jacobian[k * kTangentDim + j] = g.size() == kTangentDim ? g[j] : 0.0;
        }
      }
    }
    return true;
  }

  std::unique_ptr<ResidualBlock> clone_with(std::shared_ptr<const std::vector<Data>> data,
                                            std::vector<std::uint32_t> row_map) const override {
    return std::unique_ptr<ResidualBlock>(
        new AutoDiffBlock(functor_, std::move(data), manifolds_, this->name_, std::move(row_map)));
  }

  Functor functor_;
  std::array<std::shared_ptr<const Manifold>, sizeof...(Variables)> manifolds_;
};

/// An AutoDiffBlock over `data`: make_autodiff_block<kGroupRows, Variables...>(functor, data).
template <int kGroupRows, typename... Variables, typename Functor, typename Data>
std::shared_ptr<AutoDiffBlock<Functor, Data, kGroupRows, Variables...>> make_autodiff_block(
    Functor functor, std::vector<Data> data,
    std::array<std::shared_ptr<const Manifold>, sizeof...(Variables)> manifolds = {},
    std::string name = "AutoDiffBlock") {
  return std::make_shared<AutoDiffBlock<Functor, Data, kGroupRows, Variables...>>(
      std::move(functor), std::move(data), std::move(manifolds), std::move(name));
}

}  // namespace carat
