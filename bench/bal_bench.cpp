// The BAL reprojection error per observation: SnavelyReprojectionBlock (analytic Jacobian,
// fixed-size accumulate) beside an AutoDiffBlock of the same camera model (Eigen's
// AutoDiffScalar, 12 derivatives), each block holding one observation as in a BAL problem:
//   BM_SnavelyAccumulate/analytic|autodiff   accumulate() (H 12x12, b, c) of one observation
//   BM_SnavelyResidual/analytic|autodiff     squared_norm() of one observation (cost only)
//   BM_ParseBal / BM_WriteBal                 the BAL text of the same scene, in memory
// The observations come from a synthetic ring scene (16 cameras, 4096 points, 4 per point).
//
//   ./build/bench/bal_bench
// Compare the two arguments of one benchmark in the same run (items_per_second is observations
// per second).
#include <benchmark/benchmark.h>

#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "benchmark_main.hpp"
#include "carat/residuals/io/bal_io.hpp"
#include "carat/residuals/snavely_block.hpp"
#include "carat/residuals/snavely_camera.hpp"
#include "carat/sim/bal_scene.hpp"
#include "carat/solver/autodiff_block.hpp"

namespace {

struct SnavelyFunctor {
  template <typename T>
  bool operator()(const Eigen::Vector2d& observed, const T* camera, const T* point,
                  T* residual) const {
    T image[2];
    carat::snavely_project(camera, point, image);
    residual[0] = image[0] - observed.x();
    residual[1] = image[1] - observed.y();
    return true;
  }
};

struct Fixture {
  carat::BalProblem problem;
  std::vector<std::shared_ptr<const carat::ResidualBlock>> analytic, autodiff;
};

const Fixture& fixture() {
  static const Fixture f = [] {
    carat::BalSimulationOptions options;
    options.cameras = 16;
    options.points = 4096;
    options.observations_per_point = 4;
    Fixture out;
    out.problem = carat::simulate_bal(options).problem;
    for (const carat::BalObservation& o : out.problem.observations) {
      out.analytic.push_back(std::make_shared<carat::SnavelyReprojectionBlock>(o.x, o.y));
      out.autodiff.push_back(
          carat::make_autodiff_block<2, carat::VariableSize<9>, carat::VariableSize<3>>(
              SnavelyFunctor{}, std::vector<Eigen::Vector2d>{{o.x, o.y}}));
    }
    return out;
  }();
  return f;
}

const std::vector<std::shared_ptr<const carat::ResidualBlock>>& blocks(int which) {
  return which == 0 ? fixture().analytic : fixture().autodiff;
}

void BM_SnavelyAccumulate(benchmark::State& state) {
  const Fixture& f = fixture();
  const auto& chosen = blocks(static_cast<int>(state.range(0)));
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(12, 12);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(12);
  std::size_t k = 0;
  double c = 0.0;
  for (auto _ : state) {
    const carat::BalObservation& o = f.problem.observations[k];
    const double* params[2] = {f.problem.cameras[static_cast<std::size_t>(o.camera)].data(),
                               f.problem.points[static_cast<std::size_t>(o.point)].data()};
    c += chosen[k]->accumulate(params, H, b);
    k = k + 1 == chosen.size() ? 0 : k + 1;
  }
  benchmark::DoNotOptimize(c);
  benchmark::DoNotOptimize(H.data());
  state.SetItemsProcessed(state.iterations());
  state.SetLabel(state.range(0) == 0 ? "analytic" : "autodiff");
}
BENCHMARK(BM_SnavelyAccumulate)->Arg(0)->Arg(1);

void BM_SnavelyResidual(benchmark::State& state) {
  const Fixture& f = fixture();
  const auto& chosen = blocks(static_cast<int>(state.range(0)));
  std::size_t k = 0;
  double c = 0.0;
  for (auto _ : state) {
    const carat::BalObservation& o = f.problem.observations[k];
    const double* params[2] = {f.problem.cameras[static_cast<std::size_t>(o.camera)].data(),
                               f.problem.points[static_cast<std::size_t>(o.point)].data()};
    c += chosen[k]->squared_norm(params);
    k = k + 1 == chosen.size() ? 0 : k + 1;
  }
  benchmark::DoNotOptimize(c);
  state.SetItemsProcessed(state.iterations());
  state.SetLabel(state.range(0) == 0 ? "analytic" : "autodiff");
}
BENCHMARK(BM_SnavelyResidual)->Arg(0)->Arg(1);

std::string bal_text() {
  std::ostringstream out;
  carat::write_bal(out, fixture().problem);
  return out.str();
}

void BM_ParseBal(benchmark::State& state) {
  const std::string text = bal_text();
  for (auto _ : state) {
    const carat::BalProblem problem = carat::parse_bal(text, "bench");
    benchmark::DoNotOptimize(problem.points.data());
  }
  state.SetBytesProcessed(state.iterations() * static_cast<std::int64_t>(text.size()));
  state.SetItemsProcessed(state.iterations() *
                          static_cast<std::int64_t>(fixture().problem.observations.size()));
}
BENCHMARK(BM_ParseBal)->Unit(benchmark::kMillisecond);

void BM_WriteBal(benchmark::State& state) {
  std::size_t bytes = 0;
  for (auto _ : state) {
    std::ostringstream out;
    carat::write_bal(out, fixture().problem);
    bytes = out.str().size();
    benchmark::DoNotOptimize(bytes);
  }
  state.SetBytesProcessed(state.iterations() * static_cast<std::int64_t>(bytes));
}
BENCHMARK(BM_WriteBal)->Unit(benchmark::kMillisecond);

}  // namespace

CARAT_BENCHMARK_MAIN()
