// ReadMostly: a value read without a lock while a writer replaces it. A replaced value lives while
// a reader holds it and is freed afterwards; a thread's second Read, or a read before reads are
// enabled, is empty; readers racing a writer only ever see whole, live values (the sanitizer build
// catches a read of a freed one); reader numbers are distinct among running threads and reused
// once a thread ends.
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <memory>
#include <set>
#include <thread>
#include <vector>

#include "carat/base/read_mostly.hpp"

namespace carat {
namespace {

std::atomic<int> g_alive{0};

/// A value whose numbers all equal its generation, counted while it lives.
struct Value {
  explicit Value(long generation) {
    numbers.fill(generation);
    g_alive.fetch_add(1);
  }
  ~Value() {
    numbers.fill(-1);
    g_alive.fetch_sub(1);
  }
  Value(const Value&) = delete;
  Value& operator=(const Value&) = delete;
  std::array<long, 16> numbers{};
};

TEST(ReadMostlyTest, AReplacedValueLivesWhileReadAndIsFreedAfterwards) {
  {
    ReadMostly<Value> value;
    value.replace(std::make_unique<Value>(1));
    EXPECT_EQ(value.read().get(), nullptr);  // reads not enabled: the caller takes its lock
    value.replace(nullptr);
    EXPECT_EQ(g_alive.load(), 0);  // nothing could read it: freed at once
    value.enable_reads();
    EXPECT_EQ(value.read().get(), nullptr);
    value.replace(std::make_unique<Value>(1));
    EXPECT_EQ(g_alive.load(), 1);
    {
      const ReadMostly<Value>::Read held = value.read();
      ASSERT_NE(held.get(), nullptr);
      EXPECT_EQ(held.get()->numbers[0], 1);
      value.replace(std::make_unique<Value>(2));
      EXPECT_EQ(value.retired(), 1u);
      EXPECT_EQ(g_alive.load(), 2);
      EXPECT_EQ(held.get()->numbers[15], 1);   // still the value it read
      EXPECT_EQ(value.read().get(), nullptr);  // this thread's second Read
      EXPECT_EQ(value.current()->numbers[0], 2);
    }
    EXPECT_EQ(value.read().get()->numbers[0], 2);
    value.replace(std::make_unique<Value>(3));  // nothing holds 1 or 2 any more
    EXPECT_EQ(value.retired(), 0u);
    EXPECT_EQ(g_alive.load(), 1);
    EXPECT_EQ(value.current()->numbers[0], 3);
    value.replace(nullptr);
    EXPECT_EQ(value.read().get(), nullptr);
    EXPECT_EQ(g_alive.load(), 0);
    value.replace(std::make_unique<Value>(4));
    const ReadMostly<Value>::Read held = value.read();
    value.replace(nullptr);
    EXPECT_EQ(g_alive.load(), 1);  // held
  }
  EXPECT_EQ(g_alive.load(), 0);  // the destructor frees what is left
}

TEST(ReadMostlyTest, ReadersRacingAWriterSeeOnlyWholeLiveValues) {
  ReadMostly<Value> value;
  value.enable_reads();
  value.replace(std::make_unique<Value>(0));
  std::atomic<bool> stop{false};
  std::atomic<long> torn{0};
  std::atomic<long> reads{0};
  std::atomic<int> reading{0};
  std::vector<std::thread> readers;
  for (int t = 0; t < 3; ++t) {
    readers.emplace_back([&] {
      long last = 0;
      bool first = true;
      while (!stop.load(std::memory_order_relaxed)) {
        const ReadMostly<Value>::Read held = value.read();
        const Value* v = held.get();
        if (v == nullptr) continue;
        const long generation = v->numbers[0];
        for (long n : v->numbers) torn.fetch_add(n != generation ? 1 : 0);
        if (generation < last) torn.fetch_add(1);  // values only move forward
        last = generation;
        reads.fetch_add(1, std::memory_order_relaxed);
        if (first) reading.fetch_add(1);
        first = false;
      }
    });
  }
  while (reading.load() < 3) std::this_thread::yield();  // every reader races the writer
  for (long generation = 1; generation <= 20000; ++generation) {
    value.replace(std::make_unique<Value>(generation));
  }
  stop.store(true);
  for (std::thread& t : readers) t.join();
  EXPECT_EQ(torn.load(), 0);
  EXPECT_GE(reads.load(), 3);
  value.replace(std::make_unique<Value>(20001));  // no reader left: every replaced value freed
  EXPECT_EQ(value.retired(), 0u);
  EXPECT_EQ(g_alive.load(), 1);
}

TEST(ReadMostlyTest, RunningThreadsHoldDistinctReaderNumbersThatAreReusedAfterThem) {
  const int mine = reader_number();
  EXPECT_EQ(reader_number(), mine);
  std::array<int, 4> numbers{};
  std::atomic<int> started{0};
  std::atomic<bool> release{false};
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&, t] {
      numbers[static_cast<std::size_t>(t)] = reader_number();
      started.fetch_add(1);
      while (!release.load()) std::this_thread::yield();
    });
  }
  while (started.load() < 4) std::this_thread::yield();
  std::set<int> distinct(numbers.begin(), numbers.end());
  distinct.insert(mine);
  EXPECT_EQ(distinct.size(), 5u);
  release.store(true);
  for (std::thread& t : threads) t.join();
  int later = -1;
  std::thread([&] { later = reader_number(); }).join();
  EXPECT_EQ(std::set<int>(numbers.begin(), numbers.end()).count(later), 1u) << later;
}

}  // namespace
}  // namespace carat
