// Fuzzes the BAL reader in memory, then the problem built from what it read: any input must
// either parse or throw carat::Error, never crash, hang or leak. Run with fuzz/bal.dict
// (boundary numbers and spellings of non-finite values).
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "carat/base/error.hpp"
#include "carat/residuals/bal_problem.hpp"
#include "carat/residuals/io/bal_io.hpp"
#include "carat/solver/problem.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    const carat::BalProblem bal = carat::parse_bal(text, "fuzz.bal");
    (void)carat::count_points_behind_cameras(bal);
    (void)carat::bal_cost(bal);
    if (bal.observations.size() < 256) {
      carat::Problem problem;
      (void)carat::add_bal_problem(bal, &problem);
      (void)problem.evaluate_cost();
    }
  } catch (const carat::Error&) {
  }
  return 0;
}
