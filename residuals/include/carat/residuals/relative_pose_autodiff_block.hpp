#pragma once

/// A binary residual block over two SE(3) poses whose rows depend on them only through the
/// relative pose T_ij = T_i^-1 T_j, written once as a functor of T_ij templated on the scalar:
///
///   struct PointToLine {  // a source point against a target line (point a, unit direction d)
///     template <typename T>
///     bool operator()(const LineMatch& m, const lie::Pose<T>& T_ij, T* residuals) const {
///       const Eigen::Matrix<T, 3, 1> q = T_ij.act(m.source.cast<T>()) - m.a.cast<T>();
///       const Eigen::Matrix<T, 3, 1> off = q - m.d.cast<T>() * m.d.cast<T>().dot(q);
///       for (int k = 0; k < 3; ++k) residuals[k] = off[k];
///       return true;
///     }
///   };
///   auto block = make_relative_pose_block<3>(PointToLine{}, matches);
///
/// The block reports its Jacobian in the tangent of T_ij (reduced_dim() = 6, the derivative of
/// T_ij Exp(xi)) and the fixed map A = [-Ad(T_ij^-1) | I], so the coreset reproduces its full
/// 12 x 12 H, b, c with 29 rows, as for carat's own registration blocks. T_ij enters the functor
/// as a lie::Pose of dual numbers built once per evaluation: R (I + [omega]x) and t + R v, exact
/// to first order, which is all a first derivative sees.

#include <Eigen/Core>
#include <memory>
#include <span>
#include <string>
#include <unsupported/Eigen/AutoDiff>
#include <utility>
#include <vector>

#include "carat/residuals/registration_rows.hpp"
#include "carat/solver/grouped_rows_block.hpp"
#include "carat/solver/lie_functions.hpp"

namespace carat {

/// kGroupRows rows per datum of type Data, as functions of T_ij (target pose i, source pose j).
/// The functor has the signature
///   template <typename T> bool operator()(const Data&, const lie::Pose<T>& T_ij, T* r) const
template <typename Functor, typename Data, int kGroupRows>
class RelativePoseAutoDiffBlock final : public GroupedRowsBlock<Data, kGroupRows> {
  using Base = GroupedRowsBlock<Data, kGroupRows>;

 public:
  /// Dual numbers with the 6 derivatives of the relative pose's tangent [omega, v].
  using Dual = Eigen::AutoDiffScalar<Eigen::Matrix<double, 6, 1>>;

  /// The block over `data` (one group of rows each); `name` is used in messages. Throws
  /// carat::Error for no data.
  RelativePoseAutoDiffBlock(Functor functor, std::vector<Data> data,
                            std::string name = "RelativePoseAutoDiffBlock")
      : RelativePoseAutoDiffBlock(std::move(functor),
                                  std::make_shared<const std::vector<Data>>(std::move(data)),
                                  std::move(name), {}) {}

  int reduced_dim() const override { return 6; }
  void reduced_map(ParameterPointers params, double* A) const override {
    relative_pose_reduced_map(params, A);
  }
  void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* residuals,
                     double* jacobian) const override {
    if (!jacobian) {  // residuals only: the functor on doubles
      const lie::Pose<double> T_ij = pose_of(params);
      this->template walk_rows<6>(
          rows, residuals, nullptr, nullptr,
          [&](const Data& datum, double* e, double* /*J*/) { return functor_(datum, T_ij, e); });
      return;
    }
    const auto context = prepare(params);
    this->template walk_rows<6>(rows, residuals, jacobian, nullptr,
                                [&](const Data& datum, double* e, double* J) {
                                  return evaluate_group(*context, datum, e, J);
                                });
  }

  double accumulate(ParameterPointers params, Eigen::Ref<Eigen::MatrixXd> H_r,
                    Eigen::Ref<Eigen::VectorXd> b_r) const override {
    const auto context = prepare(params);
    return this->template accumulate_rows<6>(H_r, b_r,
                                             [&](const Data& datum, double* e, double* J) {
                                               return evaluate_group(*context, datum, e, J);
                                             });
  }

  double squared_norm(ParameterPointers params) const override {
    const lie::Pose<double> T_ij = pose_of(params);
    return this->sum_rows([&](const Data& datum, double* e) { return functor_(datum, T_ij, e); });
  }

 private:
  RelativePoseAutoDiffBlock(Functor functor, std::shared_ptr<const std::vector<Data>> data,
                            std::string name, std::vector<std::uint32_t> row_map)
      : Base(std::move(data), std::vector<int>{6, 6}, std::move(name), std::move(row_map)),
        functor_(std::move(functor)) {}

  /// T_ij in doubles; throws for a wrong variable count.
  lie::Pose<double> pose_of(ParameterPointers params) const {
    check_count(params);
    const Eigen::Isometry3d T = relative_pose(params);
    lie::Pose<double> out;
    out.R = T.linear();
    out.t = T.translation();
    return out;
  }

  void check_count(ParameterPointers params) const {
    if (params.size() != 2) {
      throw Error(this->name_ + ": " + std::to_string(params.size()) +
                  " variables given, 2 expected (T_world_i, T_world_j)");
    }
  }

  struct DualPose final : Base::Context {
    lie::Pose<Dual> T_ij;
  };

  std::unique_ptr<typename Base::Context> prepare(ParameterPointers params) const override {
    check_count(params);
    const Eigen::Isometry3d T = relative_pose(params);
    const Eigen::Matrix3d R = T.linear();
    auto out = std::make_unique<DualPose>();
    // R' = R (I + [omega]x): dR'/d omega_a = R [e_a]x; t' = t + R v: dt'/dv = R.
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        Dual& d = out->T_ij.R(r, c);
        d.value() = R(r, c);
        d.derivatives().setZero();
      }
      Dual& t = out->T_ij.t[r];
      t.value() = T.translation()[r];
      t.derivatives().setZero();
      for (int a = 0; a < 3; ++a) t.derivatives()[3 + a] = R(r, a);
    }
    for (int a = 0; a < 3; ++a) {
      Eigen::Matrix3d E = Eigen::Matrix3d::Zero();
      E((a + 2) % 3, (a + 1) % 3) = 1.0;  // [e_a]x
      E((a + 1) % 3, (a + 2) % 3) = -1.0;
      const Eigen::Matrix3d dR = R * E;
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) out->T_ij.R(r, c).derivatives()[a] = dR(r, c);
      }
    }
    return out;
  }

  bool evaluate_group(const typename Base::Context& context, const Data& datum, double* residuals,
                      double* jacobian) const override {
    const auto& pose = static_cast<const DualPose&>(context);
    std::array<Dual, kGroupRows> r;
    for (Dual& d : r) d = Dual(0.0, Eigen::Matrix<double, 6, 1>::Zero());
    if (!functor_(datum, pose.T_ij, r.data())) return false;
    for (int k = 0; k < kGroupRows; ++k) {
      residuals[k] = r[static_cast<std::size_t>(k)].value();
      if (jacobian) {
        for (int j = 0; j < 6; ++j) {
          jacobian[k * 6 + j] = r[static_cast<std::size_t>(k)].derivatives()[j];
        }
      }
    }
    return true;
  }

  std::unique_ptr<ResidualBlock> clone_with(std::shared_ptr<const std::vector<Data>> data,
                                            std::vector<std::uint32_t> row_map) const override {
    return std::unique_ptr<ResidualBlock>(
        new RelativePoseAutoDiffBlock(functor_, std::move(data), this->name_, std::move(row_map)));
  }

  Functor functor_;
};

/// A RelativePoseAutoDiffBlock: make_relative_pose_block<kGroupRows>(functor, data).
template <int kGroupRows, typename Functor, typename Data>
std::shared_ptr<RelativePoseAutoDiffBlock<Functor, Data, kGroupRows>> make_relative_pose_block(
    Functor functor, std::vector<Data> data, std::string name = "RelativePoseAutoDiffBlock") {
  return std::make_shared<RelativePoseAutoDiffBlock<Functor, Data, kGroupRows>>(
      std::move(functor), std::move(data), std::move(name));
}

}  // namespace carat
