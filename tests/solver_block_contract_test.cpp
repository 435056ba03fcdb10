// Blocks that break the row contract: an error naming the block, never a write past a buffer
// (the sanitizer build runs these), and the whole-problem check that catches what no guard can.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "carat/coreset/compress.hpp"
#include "carat/solver/autodiff_block.hpp"
#include "carat/solver/block_checker.hpp"
#include "carat/solver/lie_functions.hpp"
#include "carat/solver/solve.hpp"

namespace carat {
namespace {

/// r_i = a_i . x - y_i over x in R^2, 300 rows, with one way of breaking the contract.
class LineBlock final : public ResidualBlock {
 public:
  enum class Fault {
    kNone,
    kWritesEveryRow,
    kFirstRowsInstead,
    kLeavesOneUnwritten,
    kWrongJacobian
  };
  explicit LineBlock(Fault fault) : fault_(fault) {}
  int num_rows() const override { return kRows; }
  std::span<const int> tangent_dims() const override { return kDims; }
  void evaluate_rows(ParameterPointers params, std::span<const int> rows, double* residuals,
                     double* jacobian) const override {
    const double* x = params[0];
    const auto row = [&](int i, int k) {
      residuals[k] = a(i) * x[0] + x[1] - (2.0 * a(i) + 1.0);
      if (jacobian) {
        jacobian[2 * k] = a(i);
        jacobian[2 * k + 1] = fault_ == Fault::kWrongJacobian ? 2.0 : 1.0;
      }
    };
    switch (fault_) {
      case Fault::kWritesEveryRow:  // ignores `rows`: all 300 rows, whatever was asked
        for (int i = 0; i < kRows; ++i) row(i, i);
        return;
      case Fault::kFirstRowsInstead:
        for (std::size_t k = 0; k < rows.size(); ++k) row(static_cast<int>(k), static_cast<int>(k));
        return;
      case Fault::kLeavesOneUnwritten:
        for (std::size_t k = 0; k + 1 < rows.size(); ++k) row(rows[k], static_cast<int>(k));
        return;
      default:
        for (std::size_t k = 0; k < rows.size(); ++k) row(rows[k], static_cast<int>(k));
    }
  }
  std::size_t memory_bytes() const override { return 0; }
  const std::string& name() const override { return name_; }

 private:
  static constexpr int kRows = 300;
  static constexpr std::array<int, 1> kDims{2};
  static double a(int i) { return 0.01 * i - 1.0; }
  Fault fault_;
  std::string name_ = "line";
};

Problem line_problem(LineBlock::Fault fault) {
  Problem problem;
  const VariableId x = problem.add_euclidean(Eigen::Vector2d(0.0, 0.0));
  problem.add_residual_block(std::make_shared<LineBlock>(fault), {x});
  return problem;
}

TEST(BlockContractTest, ABlockThatWritesEveryRowIsAnErrorNotAnOverflow) {
  Problem problem = line_problem(LineBlock::Fault::kWritesEveryRow);
  const SolverSummary s = solve(SolverOptions{}, problem);
  EXPECT_EQ(s.termination, TerminationType::kFailure);
  EXPECT_NE(s.message.find("residual block 0 ('line')"), std::string::npos) << s.message;
  EXPECT_NE(s.message.find("evaluate_rows() asked for 256 rows wrote past them"), std::string::npos)
      << s.message;
  // Its compressed rows (it cannot extract them, so they are read from the whole block).
  Problem compressed = line_problem(LineBlock::Fault::kWritesEveryRow);
  const double* params[] = {compressed.value(VariableId{0}).data()};
  compressed.replace_residual_block(ResidualBlockId{0},
                                    compress(compressed.block(ResidualBlockId{0}).block, params));
  const SolverSummary c = solve(SolverOptions{}, compressed);
  EXPECT_EQ(c.termination, TerminationType::kFailure);
  EXPECT_NE(c.message.find("wrote past them"), std::string::npos) << c.message;
}

TEST(BlockContractTest, ABlockThatLeavesARowUnwrittenIsAnError) {
  Problem problem = line_problem(LineBlock::Fault::kLeavesOneUnwritten);
  const SolverSummary s = solve(SolverOptions{}, problem);
  EXPECT_EQ(s.termination, TerminationType::kFailure);
  EXPECT_NE(s.message.find("left the residual or Jacobian of row 255 (slot 255) unwritten"),
            std::string::npos)
      << s.message;
}

TEST(BlockContractTest, CheckBlocksCatchesWrongRowsAndJacobians) {
  // Rows 0..k-1 instead of the rows asked: no guard sees it; the conformance check does.
  Problem first = line_problem(LineBlock::Fault::kFirstRowsInstead);
  SolverOptions options;
  options.check_blocks = true;
  const SolverSummary s = solve(options, first);
  EXPECT_EQ(s.termination, TerminationType::kFailure);
  EXPECT_NE(s.message.find("check_blocks: residual block 0 ('line'), of type "), std::string::npos)
      << s.message;
  EXPECT_NE(s.message.find("asked in a subset differs from the full evaluation"), std::string::npos)
      << s.message;
  // A wrong Jacobian column, reported in one paragraph that names the column.
  const ProblemCheckReport report = check_problem(line_problem(LineBlock::Fault::kWrongJacobian));
  EXPECT_FALSE(report.ok);
  EXPECT_EQ(report.checked_blocks, 1);
  ASSERT_EQ(report.failures.size(), 1u);
  EXPECT_NE(report.failures[0].find("MISMATCH: 300 of 600 Jacobian entries differ"),
            std::string::npos)
      << report.failures[0];
  EXPECT_NE(report.failures[0].find("column 1 (variable 0, tangent 1)"), std::string::npos);
  EXPECT_LT(report.summary().size(), 1000u);
  // A sound block passes, and is checked once per type.
  Problem sound = line_problem(LineBlock::Fault::kNone);
  sound.add_residual_block(std::make_shared<LineBlock>(LineBlock::Fault::kNone), {VariableId{0}});
  const ProblemCheckReport ok = check_problem(sound);
  EXPECT_TRUE(ok.ok) << ok.summary();
  EXPECT_EQ(ok.checked_blocks, 1);
  EXPECT_EQ(solve(options, sound).termination, TerminationType::kConvergence);
}

/// A functor whose prepare() throws.
struct ThrowingPrepare {
  template <typename T>
  const T* prepare(const T* /*x*/) const {
    throw std::runtime_error("calibration table missing");
  }
  template <typename T>
  bool operator()(const double& y, const T* const& x, T* r) const {
    r[0] = x[0] - y;
    return true;
  }
};

TEST(BlockContractTest, AFunctorThatThrowsEndsTheSolveNamingTheBlock) {
  Problem problem;
  const VariableId x = problem.add_euclidean(Eigen::VectorXd::Constant(1, 0.0));
  problem.add_residual_block(make_autodiff_block<1, VariableSize<1>>(
                                 ThrowingPrepare{}, std::vector<double>{1.0, 2.0}, {}, "table"),
                             {x});
  const SolverSummary s = solve(SolverOptions{}, problem);
  EXPECT_EQ(s.termination, TerminationType::kFailure);
  EXPECT_NE(s.message.find("residual block 0 ('table')"), std::string::npos) << s.message;
  EXPECT_NE(s.message.find("calibration table missing"), std::string::npos) << s.message;
  EXPECT_EQ(problem.value(x)[0], 0.0);
}

/// y = exp(m x + c) that refuses (returns false) where m x + c > 2.5: only at overshooting trial
/// points, never at the start or the optimum.
struct RefusingExp {
  template <typename T>
  bool operator()(const Eigen::Vector2d& xy, const T* mc, T* r) const {
    using std::exp;
    const T z = mc[0] * xy.x() + mc[1];
    if (lie::value_of(z) > 2.5) return false;
    r[0] = T(xy.y()) - exp(z);
    return true;
  }
};

TEST(BlockContractTest, AFunctorThatRefusesOnlyAtTrialPointsOnlyRejectsThoseSteps) {
  std::vector<Eigen::Vector2d> data;
  for (int k = 0; k < 200; ++k) {
    const double x = 5.0 * k / 200.0;
    data.emplace_back(x, std::exp(0.3 * x + 0.1) + 0.05 * std::sin(7.0 * k));
  }
  Problem problem;
  const VariableId mc = problem.add_euclidean(Eigen::Vector2d(0.0, 0.0));
  problem.add_residual_block(make_autodiff_block<1, VariableSize<2>>(RefusingExp{}, data), {mc});
  const SolverSummary s = solve(SolverOptions{}, problem);
  EXPECT_EQ(s.termination, TerminationType::kConvergence) << s.message;
  EXPECT_GT(s.num_unsuccessful_steps, 0);  // the refused trial points
  EXPECT_NEAR(problem.value(mc)[0], 0.3, 0.01);
  EXPECT_NEAR(problem.value(mc)[1], 0.1, 0.02);
}

}  // namespace
}  // namespace carat
