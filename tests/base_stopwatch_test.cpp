// Stopwatch: readings in seconds that are non-negative, never go back, cover a sleep, and start
// again on restart.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "carat/base/stopwatch.hpp"

namespace carat {
namespace {

using namespace std::chrono_literals;

TEST(StopwatchTest, ReadingsAreNonNegativeAndNeverGoBack) {
  const Stopwatch stopwatch;
  double last = stopwatch.elapsed_s();
  EXPECT_GE(last, 0.0);
  for (int k = 0; k < 10000; ++k) {
    const double now = stopwatch.elapsed_s();
    ASSERT_GE(now, last) << "reading " << k;
    last = now;
  }
}

TEST(StopwatchTest, ASleepReadsAsAtLeastItsLengthInSecondsAndMilliseconds) {
  const Stopwatch stopwatch;
  std::this_thread::sleep_for(20ms);
  const double seconds = stopwatch.elapsed_s();
  const double milliseconds = stopwatch.elapsed_ms();  // read later
  EXPECT_GE(seconds, 0.020);
  EXPECT_LT(seconds, 60.0);  // seconds, not milliseconds or ticks
  EXPECT_GE(milliseconds, 1000.0 * seconds);
  EXPECT_LT(milliseconds, 1000.0 * seconds + 60000.0);
}

TEST(StopwatchTest, RestartStartsAgainAndReturnsTheTimeBefore) {
  Stopwatch restarted;
  std::this_thread::sleep_for(20ms);
  const Stopwatch younger;  // starts at least 20 ms after `restarted`
  std::this_thread::sleep_for(5ms);
  const double young = younger.elapsed_s();
  const double old = restarted.elapsed_s();  // read later, started earlier
  EXPECT_GE(old - young, 0.019);
  const double returned = restarted.restart();
  EXPECT_GE(returned, old);
  // Now `restarted` started after `younger`: read first, it must show no more time.
  const double after = restarted.elapsed_s();
  const double young_after = younger.elapsed_s();
  EXPECT_GE(after, 0.0);
  EXPECT_LE(after, young_after);
}

}  // namespace
}  // namespace carat
