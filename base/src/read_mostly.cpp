#include "carat/base/read_mostly.hpp"

#include <mutex>

namespace carat {

namespace {

/// The numbers running threads hold.
class ReaderNumbers {
 public:
  /// The process's one set, never freed: threads can end after static objects are destroyed.
  static ReaderNumbers& all() {
    static ReaderNumbers* const numbers = new ReaderNumbers;
    return *numbers;
  }
  /// The lowest free number, now held.
  int take() {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto free = std::find(used_.begin(), used_.end(), false);
    if (free != used_.end()) {
      *free = true;
      return static_cast<int>(free - used_.begin());
    }
    used_.push_back(true);
    return static_cast<int>(used_.size()) - 1;
  }
  /// Frees `number`.
  void give_back(int number) {
    std::lock_guard<std::mutex> lock(mutex_);
    used_[static_cast<std::size_t>(number)] = false;
  }

 private:
  std::mutex mutex_;
  std::vector<bool> used_;
};

/// A thread's number, held while the thread runs.
struct ThreadNumber {
  ThreadNumber() : number(ReaderNumbers::all().take()) {}
  ~ThreadNumber() { ReaderNumbers::all().give_back(number); }
  ThreadNumber(const ThreadNumber&) = delete;
  ThreadNumber& operator=(const ThreadNumber&) = delete;
  int number;
};

}  // namespace

int reader_number() {
  thread_local const ThreadNumber held;
  return held.number;
}

}  // namespace carat
