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
/// Residual-only evaluations (every cost evaluation of a solve) call the functor with plain
/// doubles. Jacobians use Eigen's AutoDiffScalar (forward-mode dual numbers, shipped with
/// Eigen) with a fixed derivative size D = the sum of the variables' tangent sizes, no wider:
/// a variable enters as x + P delta with P = Manifold::plus_jacobian(x), built once per
/// evaluation (a Euclidean variable's P is the identity and costs nothing), so a SubsetManifold
/// that holds coordinates also narrows the duals.
///
/// **Work once per evaluation.** A functor may also define
///
///   template <typename T> View<T> prepare(const T* x0, ..., const T* xn) const;
///   template <typename T> bool operator()(const Data&, const View<T>& view, T* residuals) const;
///
/// carat then calls prepare() once per evaluation of the block (once with doubles for a cost
/// pass, once with dual numbers for a linearization) and passes its result to every datum:
/// per-variable work (a quaternion turned into a rotation matrix and inverted, a calibration
/// matrix assembled) is done once instead of once per row. `View<T>` is any type the functor
/// chooses; pointers to the x arrays stay valid while it is used.
///
/// Any subset of rows can be evaluated, so the block compresses; extract_rows() copies the data
/// of the selected groups only. A functor that returns false makes its rows NaN: the solver
/// rejects a trial step there, and names the block and the row if it happens at the start.
/// with_group_loss() applies a robust loss to each datum's rows (grouped_rows_block.hpp).

#include <Eigen/Core>
#include <array>
#include <memory>
#include <string>
#include <tuple>
#include <type_traits>
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

namespace internal {

/// Whether F has prepare(const T*, ...) with one pointer per index.
template <typename F, typename T, std::size_t... I>
concept HasPrepareWith = requires(const F& f, const T* x) {
  f.prepare(((void)I, x)...);
};

/// Whether F defines prepare() for n variables of scalar T.
template <typename F, typename T, std::size_t N>
constexpr bool has_prepare() {
  return []<std::size_t... I>(std::index_sequence<I...>) { return HasPrepareWith<F, T, I...>; }
  (std::make_index_sequence<N>{});
}

}  // namespace internal

/// An automatically differentiated block: kGroupRows rows per datum of type Data over the
/// variables `Variables...` (VariableSize types). The functor has the signature
///   template <typename T> bool operator()(const Data&, const T* x0, ..., T* residuals) const
/// with one ambient array per variable and kGroupRows residuals, or the prepare() form of the
/// file comment.
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
  /// Whether the functor computes per-evaluation work in prepare() (see the file comment).
  static constexpr bool kPrepares =
      internal::has_prepare<Functor, double, sizeof...(Variables)>() &&
      internal::has_prepare<Functor, Dual, sizeof...(Variables)>();

  static_assert(internal::has_prepare<Functor, double, sizeof...(Variables)>() ==
                    internal::has_prepare<Functor, Dual, sizeof...(Variables)>(),
                "the functor's prepare() must be a template over the scalar, taking one const T* "
                "per variable");

  /// The block over `data` (one group of rows each). `manifolds` may leave entries null for the
  /// defaults (default_manifold()); `name` is used in messages. Throws carat::Error for no data
  /// or a manifold whose sizes differ from the variable's.
  AutoDiffBlock(Functor functor, std::vector<Data> data,
                std::array<std::shared_ptr<const Manifold>, sizeof...(Variables)> manifolds = {},
                std::string name = "AutoDiffBlock")
      : AutoDiffBlock(std::move(functor),
                      std::make_shared<const std::vector<Data>>(std::move(data)),
                      std::move(manifolds), std::move(name), {}) {}

  void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* residuals,
                     double* jacobian) const override {
    check_count(params);
    if (!jacobian) {
      const auto view = prepared(pointers(params));
      this->template walk_rows<kTangentDim>(
          rows, residuals, nullptr, nullptr,
          [&](const Data& datum, double* e, double* /*J*/) { return call(view, datum, e); });
      return;
    }
    std::array<Dual, kAmbientSize> x;
    seed(params, x);
    const auto view = prepared(dual_pointers(x));
    this->template walk_rows<kTangentDim>(
        rows, residuals, jacobian, nullptr,
        [&](const Data& datum, double* e, double* J) { return differentiate(view, datum, e, J); });
  }

  double accumulate(ParameterPointers params, Eigen::Ref<Eigen::MatrixXd> H_r,
                    Eigen::Ref<Eigen::VectorXd> b_r) const override {
    check_count(params);
    std::array<Dual, kAmbientSize> x;
    seed(params, x);
    const auto view = prepared(dual_pointers(x));
    return this->template accumulate_rows<kTangentDim>(
        H_r, b_r,
        [&](const Data& datum, double* e, double* J) { return differentiate(view, datum, e, J); });
  }

  const Manifold* jacobian_manifold(int i) const override {
    return i >= 0 && static_cast<std::size_t>(i) < manifolds_.size()
               ? manifolds_[static_cast<std::size_t>(i)].get()
               : nullptr;
  }

  double squared_norm(ParameterPointers params) const override {
    check_count(params);
    const auto view = prepared(pointers(params));
    return this->sum_rows([&](const Data& datum, double* e) { return call(view, datum, e); });
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
      identity_plus_[i] = dynamic_cast<const EuclideanManifold*>(manifolds_[i].get()) != nullptr;
    }
  }

  void check_count(ParameterPointers params) const {
    if (params.size() != sizeof...(Variables)) {
      throw Error(this->name_ + ": " + std::to_string(params.size()) + " variables given, " +
                  std::to_string(sizeof...(Variables)) + " expected");
    }
  }

  /// The variables as dual numbers x + P delta at delta = 0.
  void seed(ParameterPointers params, std::array<Dual, kAmbientSize>& x) const {
    [&]<std::size_t... I>(std::index_sequence<I...>) { (seed_variable<I>(params[I], x), ...); }
    (std::index_sequence_for<Variables...>{});
  }

  template <std::size_t I>
  void seed_variable(const double* value, std::array<Dual, kAmbientSize>& x) const {
    constexpr int a = kAmbient[I], t = kTangent[I];
    constexpr int ambient_offset = kAmbientOffset[I], tangent_offset = kTangentOffset[I];
    std::array<double, static_cast<std::size_t>(a * t)> P;
    const bool identity = a == t && identity_plus_[I];
    if (!identity) manifolds_[I]->plus_jacobian(value, P.data());
    for (int k = 0; k < a; ++k) {
      Dual& d = x[static_cast<std::size_t>(ambient_offset + k)];
      d.value() = value[k];
      d.derivatives().setZero();
      if constexpr (a == t) {
        if (identity) {
          d.derivatives()[tangent_offset + k] = 1.0;
          continue;
        }
      }
      for (int j = 0; j < t; ++j) {
        d.derivatives()[tangent_offset + j] = P[static_cast<std::size_t>(k * t + j)];
      }
    }
  }

  static std::array<const double*, sizeof...(Variables)> pointers(ParameterPointers params) {
    std::array<const double*, sizeof...(Variables)> out{};
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = params[i];
    return out;
  }

  static std::array<const Dual*, sizeof...(Variables)> dual_pointers(
      const std::array<Dual, kAmbientSize>& x) {
    std::array<const Dual*, sizeof...(Variables)> out{};
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = x.data() + kAmbientOffset[i];
    return out;
  }

  /// The functor's prepare() result, or the pointers themselves when it has none.
  template <typename T>
  auto prepared(const std::array<const T*, sizeof...(Variables)>& x) const {
    if constexpr (kPrepares) {
      return std::apply([&](const auto*... p) { return functor_.prepare(p...); }, x);
    } else {
      return x;
    }
  }

  template <typename T, typename View>
  bool call(const View& view, const Data& datum, T* residuals) const {
    if constexpr (kPrepares) {
      return functor_(datum, view, residuals);
    } else {
      return std::apply([&](const auto*... p) { return functor_(datum, p..., residuals); }, view);
    }
  }

  template <typename View>
  bool differentiate(const View& view, const Data& datum, double* residuals,
                     double* jacobian) const {
    std::array<Dual, kGroupRows> r;
    for (Dual& d : r) d = Dual(0.0, Eigen::Matrix<double, kTangentDim, 1>::Zero());
    if (!call(view, datum, r.data())) return false;
    for (int k = 0; k < kGroupRows; ++k) {
      const Dual& d = r[static_cast<std::size_t>(k)];
      residuals[k] = d.value();
      Eigen::Map<Eigen::Matrix<double, kTangentDim, 1>>(jacobian + k * kTangentDim) =
          d.derivatives();
    }
    return true;
  }

  // The generic GroupedRowsBlock path (unused: every evaluation above is direct).
  struct DualValues final : Base::Context {
    std::array<Dual, kAmbientSize> x;
  };
  std::unique_ptr<typename Base::Context> prepare(ParameterPointers params) const override {
    check_count(params);
    auto out = std::make_unique<DualValues>();
    seed(params, out->x);
    return out;
  }
  bool evaluate_group(const typename Base::Context& context, const Data& datum, double* residuals,
                      double* jacobian) const override {
    const auto view = prepared(dual_pointers(static_cast<const DualValues&>(context).x));
    if (jacobian) return differentiate(view, datum, residuals, jacobian);
    std::array<Dual, kGroupRows> r;
    for (Dual& d : r) d = Dual(0.0, Eigen::Matrix<double, kTangentDim, 1>::Zero());
    if (!call(view, datum, r.data())) return false;
    for (int k = 0; k < kGroupRows; ++k) residuals[k] = r[static_cast<std::size_t>(k)].value();
    return true;
  }

  std::unique_ptr<ResidualBlock> clone_with(std::shared_ptr<const std::vector<Data>> data,
                                            std::vector<std::uint32_t> row_map) const override {
    return std::unique_ptr<ResidualBlock>(
        new AutoDiffBlock(functor_, std::move(data), manifolds_, this->name_, std::move(row_map)));
  }

  Functor functor_;
  std::array<std::shared_ptr<const Manifold>, sizeof...(Variables)> manifolds_;
  std::array<bool, sizeof...(Variables)> identity_plus_{};  ///< Euclidean: P is the identity
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
