#include "carat/solver/subset_manifold.hpp"

#include <algorithm>
#include <string>
#include <vector>

#include "carat/base/error.hpp"

namespace carat {

SubsetManifold::SubsetManifold(int size, std::vector<int> constant_coordinates)
    : SubsetManifold(euclidean_manifold(size), std::move(constant_coordinates)) {}

SubsetManifold::SubsetManifold(std::shared_ptr<const Manifold> base,
                               std::vector<int> constant_coordinates)
    : base_(std::move(base)), held_(std::move(constant_coordinates)) {
  if (!base_) throw Error("SubsetManifold: the base manifold is null");
  const int t = base_->tangent_size();
  std::sort(held_.begin(), held_.end());
  for (std::size_t k = 0; k < held_.size(); ++k) {
    if (held_[k] < 0 || held_[k] >= t) {
      throw Error("SubsetManifold: coordinate " + std::to_string(held_[k]) + " is out of range (" +
                  base_->name() + " has " + std::to_string(t) + " tangent coordinates)");
    }
    if (k > 0 && held_[k] == held_[k - 1]) {
      throw Error("SubsetManifold: coordinate " + std::to_string(held_[k]) + " is held twice");
    }
  }
  for (int c = 0; c < t; ++c) {
    if (!std::binary_search(held_.begin(), held_.end(), c)) free_.push_back(c);
  }
  if (free_.empty()) {
    throw Error("SubsetManifold: every coordinate of " + std::string(base_->name()) +
                " is held; hold a whole variable with Problem::set_constant()");
  }
  name_ = "subset(" + std::string(base_->name()) + ")";
}

void SubsetManifold::plus(const double* x, const double* delta, double* x_plus_delta) const {
  std::vector<double> full(static_cast<std::size_t>(base_->tangent_size()), 0.0);
  for (std::size_t k = 0; k < free_.size(); ++k) {
    full[static_cast<std::size_t>(free_[k])] = delta[k];
  }
  base_->plus(x, full.data(), x_plus_delta);
}

void SubsetManifold::minus(const double* y, const double* x, double* delta) const {
  std::vector<double> full(static_cast<std::size_t>(base_->tangent_size()));
  base_->minus(y, x, full.data());
  for (std::size_t k = 0; k < free_.size(); ++k) {
    delta[k] = full[static_cast<std::size_t>(free_[k])];
  }
}

void SubsetManifold::plus_jacobian(const double* x, double* jacobian) const {
  const int a = base_->ambient_size();
  const int t = base_->tangent_size();
  std::vector<double> full(static_cast<std::size_t>(a * t));
  base_->plus_jacobian(x, full.data());
  const auto free = static_cast<int>(free_.size());
  for (int i = 0; i < a; ++i) {
    for (int k = 0; k < free; ++k) {
      jacobian[i * free + k] =
          full[static_cast<std::size_t>(i * t + free_[static_cast<std::size_t>(k)])];
    }
  }
}

}  // namespace carat
