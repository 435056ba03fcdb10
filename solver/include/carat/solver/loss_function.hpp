#pragma once

/// Robust losses rho(s) applied to a residual block's squared norm s = |r|^2 (Ceres's
/// convention: the block's cost is 1/2 rho(s)).

#include <memory>
#include <string_view>

namespace carat {

/// rho(s) and its first two derivatives at s.
struct LossValue {
  double rho = 0.0;   ///< rho(s)
  double rho1 = 1.0;  ///< rho'(s)
  double rho2 = 0.0;  ///< rho''(s)
};

/// A robust loss rho(s) of a block's squared residual norm s >= 0; rho(0) = 0, rho'(0) = 1.
class LossFunction {
 public:
  virtual ~LossFunction() = default;
  /// rho(s), rho'(s), rho''(s).
  virtual LossValue evaluate(double s) const = 0;
  /// Short name for reports.
  virtual const char* name() const = 0;
};

/// Huber: rho(s) = s for s <= d^2, 2 d sqrt(s) - d^2 beyond (d: scale in residual units).
class HuberLoss final : public LossFunction {
 public:
  /// delta in [1e-150, 1e150] (so that delta^2 is a normal double) is the residual norm where
  /// the loss turns linear; throws carat::Error otherwise.
  explicit HuberLoss(double delta);
  LossValue evaluate(double s) const override;
  const char* name() const override { return "huber"; }

 private:
  double delta_;
};

/// Cauchy: rho(s) = c^2 log(1 + s / c^2) (c: scale in residual units).
class CauchyLoss final : public LossFunction {
 public:
  /// scale in [1e-150, 1e150] (so that scale^2 is a normal double) is the residual norm where
  /// the loss starts to flatten; throws carat::Error otherwise.
  explicit CauchyLoss(double scale);
  LossValue evaluate(double s) const override;
  const char* name() const override { return "cauchy"; }

 private:
  double c2_;
};

/// A kernel on the excess over an offset: rho(s) = s for s <= offset and
/// offset + inner(s - offset) beyond, so the first `offset` of the squared norm (e.g. a factor's
/// own minimum) stays plain least squares and only what lies above it is robustified.
class ExcessLoss final : public LossFunction {
 public:
  /// offset >= 0 and finite; inner is not null.
  ExcessLoss(double offset, std::shared_ptr<const LossFunction> inner);
  LossValue evaluate(double s) const override;
  const char* name() const override { return "excess"; }
  /// The squared norm below which the loss is plain least squares.
  double offset() const { return offset_; }

 private:
  double offset_;
  std::shared_ptr<const LossFunction> inner_;
};

/// The losses a setting (a command-line option, a configuration file) can name.
enum class LossKind {
  kNone,    ///< plain least squares: no LossFunction
  kHuber,   ///< HuberLoss
  kCauchy,  ///< CauchyLoss
};

/// Name of a loss kind: "none", "huber" or "cauchy" (for kHuber and kCauchy, the loss's name()).
const char* to_string(LossKind kind);
/// Parses "none", "huber" or "cauchy"; throws carat::Error listing them otherwise.
LossKind parse_loss_kind(std::string_view name);
/// The loss of `kind` with `scale` in residual units (HuberLoss's delta, CauchyLoss's scale):
/// null for kNone (scale unused). Throws carat::Error for a scale the loss refuses.
std::shared_ptr<const LossFunction> make_loss(LossKind kind, double scale);

}  // namespace carat
