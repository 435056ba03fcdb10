#include "carat/solver/loss_function.hpp"

#include <cmath>
#include <cstdio>
#include <string>
#include <utility>

#include "carat/base/error.hpp"

namespace carat {

namespace {

/// Scales whose square is a normal double (so that the loss's own arithmetic cannot overflow or
/// divide by zero): [1e-150, 1e150].
constexpr double kMinScale = 1e-150;
constexpr double kMaxScale = 1e150;

std::string scale_text(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%g", value);
  return buffer;
}

}  // namespace

HuberLoss::HuberLoss(double delta) : delta_(delta) {
  if (!(delta >= kMinScale && delta <= kMaxScale)) {
    throw Error("HuberLoss: delta must be in [1e-150, 1e150], got " + scale_text(delta));
  }
}

LossValue HuberLoss::evaluate(double s) const {
  const double b = delta_ * delta_;
  if (s <= b) return {s, 1.0, 0.0};
  const double r = std::sqrt(s);
  return {2.0 * delta_ * r - b, delta_ / r, -0.5 * delta_ / (s * r)};
}

CauchyLoss::CauchyLoss(double scale) : c2_(scale * scale) {
  if (!(scale >= kMinScale && scale <= kMaxScale)) {
    throw Error("CauchyLoss: scale must be in [1e-150, 1e150], got " + scale_text(scale));
  }
}

LossValue CauchyLoss::evaluate(double s) const {
  const double inv = 1.0 / c2_;
  const double sum = 1.0 + s * inv;
  const double rho1 = 1.0 / sum;
  return {c2_ * std::log1p(s * inv), rho1, -inv * rho1 * rho1};
}

ExcessLoss::ExcessLoss(double offset, std::shared_ptr<const LossFunction> inner)
    : offset_(offset), inner_(std::move(inner)) {
  if (!(offset >= 0.0) || !std::isfinite(offset)) {
    throw Error("ExcessLoss: offset must be finite and >= 0, got " + std::to_string(offset));
  }
  if (!inner_) throw Error("ExcessLoss: the inner loss is null");
}

LossValue ExcessLoss::evaluate(double s) const {
  if (!(s > offset_)) return {s, 1.0, 0.0};
  const LossValue v = inner_->evaluate(s - offset_);
  return {offset_ + v.rho, v.rho1, v.rho2};
}

const char* to_string(LossKind kind) {
  switch (kind) {
    case LossKind::kNone:
      return "none";
    case LossKind::kHuber:
      return "huber";
    case LossKind::kCauchy:
      return "cauchy";
  }
  return "unknown";
}

LossKind parse_loss_kind(std::string_view name) {
  if (name == "none") return LossKind::kNone;
  if (name == "huber") return LossKind::kHuber;
  if (name == "cauchy") return LossKind::kCauchy;
  throw Error("unknown loss " + quote_bytes(name) + " (valid: none, huber, cauchy)");
}

std::shared_ptr<const LossFunction> make_loss(LossKind kind, double scale) {
  switch (kind) {
    case LossKind::kNone:
      return nullptr;
    case LossKind::kHuber:
      return std::make_shared<HuberLoss>(scale);
    case LossKind::kCauchy:
      return std::make_shared<CauchyLoss>(scale);
  }
  throw Error("make_loss: unknown loss kind");
}

}  // namespace carat
