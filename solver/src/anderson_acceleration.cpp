#include "anderson_acceleration.hpp"

#include <Eigen/QR>

namespace carat::internal {

void AndersonAcceleration::push(const Eigen::VectorXd& solved, const Eigen::VectorXd& taken) {
  if (memory_ <= 0) return;
  if (static_cast<int>(history_.size()) == memory_) history_.pop_front();
  history_.push_back({solved, taken});
}

bool AndersonAcceleration::propose(const Eigen::VectorXd& solved, Eigen::VectorXd* out) const {
  const int m = static_cast<int>(history_.size());
  if (m == 0) return false;
  const Eigen::Index n = solved.size();
  Eigen::MatrixXd dF(n, m);
  Eigen::MatrixXd dX(n, m);
  for (int j = 0; j < m; ++j) {
    const Eigen::VectorXd& next = j + 1 < m ? history_[j + 1].solved : solved;
    dF.col(j) = next - history_[j].solved;
    dX.col(j) = history_[j].taken;
  }
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(dF);
  if (qr.rank() == 0) return false;  // a rank-deficient dF: the basic solution, zeros elsewhere
  const Eigen::VectorXd gamma = qr.solve(solved);
  Eigen::VectorXd step = solved - (dX + dF) * gamma;
  if (!step.allFinite()) return false;
  *out = std::move(step);
  return true;
}

}  // namespace carat::internal
