#include "carat/coreset/quadratic_model.hpp"

#include <cmath>

#include "carat/base/error.hpp"

namespace carat {
namespace {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

QuadraticModel accumulate(const Eigen::Ref<const RowMatrix>& J,
                          const Eigen::Ref<const Eigen::VectorXd>& e, std::span<const int> rows,
                          std::span<const double> weights, bool all) {
  const Eigen::Index r = J.cols();
  using LMatrix = Eigen::Matrix<long double, Eigen::Dynamic, Eigen::Dynamic>;
  using LVector = Eigen::Matrix<long double, Eigen::Dynamic, 1>;
  LMatrix H = LMatrix::Zero(r, r);
  LVector b = LVector::Zero(r);
  long double c = 0.0L;
  const Eigen::Index n = all ? J.rows() : static_cast<Eigen::Index>(rows.size());
  for (Eigen::Index k = 0; k < n; ++k) {
    const Eigen::Index i = all ? k : rows[static_cast<std::size_t>(k)];
    const long double w =
        all ? 1.0L : static_cast<long double>(weights[static_cast<std::size_t>(k)]);
    const auto a = J.row(i).cast<long double>();
    const long double ei = e[i];
    H.noalias() += w * a.transpose() * a;
    b.noalias() += w * ei * a.transpose();
    c += w * ei * ei;
  }
  return {H.cast<double>(), b.cast<double>(), static_cast<double>(c)};
}

double relative(double difference, double reference) {
  return reference > 0.0 ? difference / reference : difference;
}

}  // namespace

QuadraticModel quadratic_model(const Eigen::Ref<const RowMatrix>& J_r,
                               const Eigen::Ref<const Eigen::VectorXd>& e) {
  return accumulate(J_r, e, {}, {}, true);
}

QuadraticModel quadratic_model(const Eigen::Ref<const RowMatrix>& J_r,
                               const Eigen::Ref<const Eigen::VectorXd>& e,
                               std::span<const int> rows, std::span<const double> weights) {
  if (rows.size() != weights.size())
    throw Error("quadratic_model: rows and weights differ in length");
  return accumulate(J_r, e, rows, weights, false);
}

QuadraticModelError relative_error(const QuadraticModel& reference,
                                   const QuadraticModel& approximation) {
  QuadraticModelError out;
  out.H = relative((reference.H - approximation.H).norm(), reference.H.norm());
  out.b = relative((reference.b - approximation.b).norm(), reference.b.norm());
  out.c = relative(std::abs(reference.c - approximation.c), std::abs(reference.c));
  return out;
}

}  // namespace carat
