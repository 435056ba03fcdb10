// The Jacobian checker: a block whose Jacobian is wrong in one column is flagged there.
#include <gtest/gtest.h>

#include <array>
#include <span>

#include "carat/solver/jacobian_checker.hpp"
#include "carat/solver/manifold.hpp"
#include "carat/solver/residual_block.hpp"

namespace carat {
namespace {

TEST(JacobianCheckerTest, CatchesAWrongJacobian) {
  // A block whose Jacobian is off by a factor of 2 in one column must be flagged.
  class WrongBlock final : public ResidualBlock {
   public:
    int num_rows() const override { return 1; }
    std::span<const int> tangent_dims() const override { return dims_; }
    void evaluate_rows(ParameterPointers p, std::span<const int> rows, double* r,
                       double* J) const override {
      for (std::size_t k = 0; k < rows.size(); ++k) {
        r[k] = p[0][0] * p[0][0] + p[0][1];
        if (J) {
          J[2 * k] = 4.0 * p[0][0];  // should be 2 x0
          J[2 * k + 1] = 1.0;
        }
      }
    }
    std::size_t memory_bytes() const override { return 0; }

   private:
    std::array<int, 1> dims_{2};
  };
  const WrongBlock block;
  const double x[2] = {1.5, -0.5};
  const double* params[1] = {x};
  const auto m = euclidean_manifold(2);
  const Manifold* manifolds[1] = {m.get()};
  const JacobianCheckResult result = check_jacobians(block, manifolds, params);
  EXPECT_FALSE(result.ok);
  EXPECT_EQ(result.worst_col, 0);
  EXPECT_NEAR(result.max_abs_error, 3.0, 1e-6);
}

}  // namespace
}  // namespace carat
