#include "carat/solver/loss_function.hpp"

#include <cmath>
#include <string>

#include "carat/solver/error.hpp"

namespace carat {

HuberLoss::HuberLoss(double delta) : delta_(delta) {
  if (!(delta > 0.0) || !std::isfinite(delta)) {
    throw Error("HuberLoss: delta must be finite and > 0, got " + std::to_string(delta));
  }
}

LossValue HuberLoss::evaluate(double s) const {
  const double b = delta_ * delta_;
  if (s <= b) return {s, 1.0, 0.0};
  const double r = std::sqrt(s);
  return {2.0 * delta_ * r - b, delta_ / r, -0.5 * delta_ / (s * r)};
}

CauchyLoss::CauchyLoss(double scale) : c2_(scale * scale) {
  if (!(scale > 0.0) || !std::isfinite(scale)) {
    throw Error("CauchyLoss: scale must be finite and > 0, got " + std::to_string(scale));
  }
}

LossValue CauchyLoss::evaluate(double s) const {
  const double inv = 1.0 / c2_;
  const double sum = 1.0 + s * inv;
  const double rho1 = 1.0 / sum;
  return {c2_ * std::log1p(s * inv), rho1, -inv * rho1 * rho1};
}

}  // namespace carat
