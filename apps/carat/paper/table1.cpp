// carat paper, Table I: coreset time vs M at N = 30 000 (random J, e), beside Eigen's H, b, c.
#include <algorithm>

#include "carat/base/statistics.hpp"
#include "carat/coreset/quadratic_model.hpp"
#include "carat/coreset/row_coreset.hpp"
#include "coreset_timing.hpp"
#include "paper.hpp"
#include "published.hpp"
#include "report_table.hpp"

namespace carat::cli::paper {

void table_one(const PaperArgs& args, Report* report) {
  const int trials = args.quick ? 10 : 100;
  const long n = 30000;
  const std::vector<int> targets(published::kTable1Rows.begin(), published::kTable1Rows.end());
  RandomRowSource source(args.seed, 1.0);
  std::vector<RowCoresetOptions> options(targets.size());
  for (std::size_t m = 0; m < targets.size(); ++m) options[m].target_rows = targets[m];
  std::vector<std::vector<double>> times(targets.size());
  std::vector<double> errors(targets.size(), 0.0), eigen_times;
  RowMajorMatrix J;
  Eigen::VectorXd e;
  for (int t = 0; t < trials; ++t) {
    source.draw(n, 6, &J, &e);
    for (RowCoresetOptions& o : options) o.seed = args.seed + static_cast<std::uint64_t>(t);
    const CoresetTrial trial = time_coreset_trial(J, e, options, t);
    eigen_times.push_back(trial.reference_ms);
    const QuadraticModel reference = quadratic_model(J, e);
    for (std::size_t m = 0; m < targets.size(); ++m) {
      const RowCoreset& coreset = trial.coresets[m];
      times[m].push_back(trial.coreset_ms[m]);
      errors[m] = std::max(
          errors[m],
          relative_error(reference, quadratic_model(J, e, coreset.rows, coreset.weights)).max());
    }
  }
  const double eigen_ms = median(eigen_times);
  std::string& md = report->markdown;
  md += "## Table I: coreset time vs M (N = 30 000, random J and e, " + std::to_string(trials) +
        " trials)\n\n";
  md += "The reference is forming H, b, c once with Eigen on the same data in the same run (" +
        fmt("%.3f", eigen_ms) +
        " ms median). The paper's times are the authors' code on their machine (the same "
        "N = 30,000, D = 6); \"paper / carat\" is how many times faster carat's coreset is "
        "here.\n\n";
  ReportTable table({"M", "coreset median [ms]", "/ Eigen H, b, c", "max relative error (H, b, c)",
                     "paper [ms]", "paper / carat"});
  for (std::size_t m = 0; m < targets.size(); ++m) {
    const double ms = median(times[m]);
    const double paper_ms = published::kTable1Ms[m];
    table.add_row({std::to_string(targets[m]), fmt("%.3f", ms), fmt("%.2f", ms / eigen_ms),
                   fmt("%.1e", errors[m]), fmt("%.2f", paper_ms), fmt("%.1f", paper_ms / ms)},
                  {{"M", targets[m]},
                   {"median_ms", ms},
                   {"ratio_to_eigen", ms / eigen_ms},
                   {"max_relative_error", errors[m]},
                   {"paper_ms", paper_ms},
                   {"speedup_over_paper", paper_ms / ms}});
  }
  md += table.markdown() + "\n";
  report->json["table1"] = {
      {"N", n}, {"trials", trials}, {"eigen_median_ms", eigen_ms}, {"rows", table.json()}};
}

}  // namespace carat::cli::paper
