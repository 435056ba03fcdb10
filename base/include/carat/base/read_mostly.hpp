#pragma once

/// A value that many threads read without a lock while a writer now and then replaces it, e.g. an
/// evaluation every residual block of a pass reads. A reader marks the value it reads in a slot of
/// its own (a hazard pointer: one cache line per thread, so readers never write a line another
/// thread writes); a replaced value is freed only once no slot marks it. Replacements are the
/// caller's to serialize (its own lock); a read costs two loads of the shared pointer and two
/// stores to the thread's own slot (the first a full fence), and writes no line another thread
/// reads in the meantime. A thread holds one Read of a ReadMostly at a time: a second read() while
/// the first lives is empty (the caller then takes its lock), as is every read() before
/// enable_reads().

#include <algorithm>
#include <atomic>
#include <memory>
#include <vector>

namespace carat {

/// The calling thread's reader number, >= 0: the lowest number no other running thread holds,
/// taken on the thread's first call and given back when the thread ends.
int reader_number();

/// A value of type T read without a lock (see the file comment).
template <class T>
class ReadMostly {
 public:
  /// Threads that read without the lock (reader_number() below it); others get an empty Read.
  static constexpr int kReaders = 64;

  /// The current value as a reader holds it: valid while the Read lives, which ends on the thread
  /// that read it.
  class Read {
   public:
    /// An empty Read (get() is null).
    Read() = default;
    Read(const Read&) = delete;
    Read& operator=(const Read&) = delete;
    /// Takes over `other`'s mark (on the same thread); `other` is left unmarking nothing.
    Read(Read&& other) noexcept : value_(other.value_), mark_(other.mark_) {
      other.mark_ = nullptr;
    }
    Read& operator=(Read&&) = delete;
    /// Unmarks the value: a writer may free it from now on.
    ~Read() {
      if (mark_ != nullptr) mark_->store(nullptr, std::memory_order_release);
    }
    /// The value, or null (none is set, or this thread reads under the caller's lock instead).
    const T* get() const { return value_; }

   private:
    friend class ReadMostly;
    Read(const T* value, std::atomic<const T*>* mark) : value_(value), mark_(mark) {}
    const T* value_ = nullptr;
    std::atomic<const T*>* mark_ = nullptr;
  };

  /// No value, reads not yet enabled.
  ReadMostly() = default;
  ReadMostly(const ReadMostly&) = delete;
  ReadMostly& operator=(const ReadMostly&) = delete;
  /// Frees every value; no Read may outlive it.
  ~ReadMostly() = default;

  /// Lets read() mark values (allocates the readers' slots, kReaders cache lines); call it before
  /// any thread reads.
  void enable_reads() {
    if (readers_ == nullptr) readers_ = std::make_unique<Reader[]>(kReaders);
  }

  /// The current value, marked for this thread until the Read ends (empty when none is set,
  /// reads are not enabled, the thread's reader_number() is kReaders or more, or the thread
  /// already holds a Read of this ReadMostly).
  Read read() const {
    if (readers_ == nullptr) return {};
    const int number = reader_number();
    if (number >= kReaders) return {};
    std::atomic<const T*>& mark = readers_[static_cast<std::size_t>(number)].mark;
    if (mark.load(std::memory_order_relaxed) != nullptr) return {};  // a Read of its own lives
    const T* value = current_.load(std::memory_order_acquire);
    while (value != nullptr) {
      mark.store(value, std::memory_order_seq_cst);
      const T* again = current_.load(std::memory_order_seq_cst);
      if (again == value) return {value, &mark};
      value = again;
    }
    mark.store(nullptr, std::memory_order_release);
    return {};
  }

  /// The current value, or null (for the writer, under the caller's lock).
  T* current() const { return owned_.get(); }

  /// Makes `fresh` (may be null) the current value. Calls must not overlap (the caller's lock);
  /// reads may. The replaced value is freed now if no Read holds it, else by a later replace() or
  /// the destructor.
  void replace(std::unique_ptr<T> fresh) {
    retired_.reserve(retired_.size() + 1);  // nothing below throws once `fresh` is published
    current_.store(fresh.get(), std::memory_order_seq_cst);
    if (owned_ != nullptr) retired_.push_back(std::move(owned_));
    owned_ = std::move(fresh);
    if (readers_ == nullptr) {  // nothing reads without the lock
      retired_.clear();
      return;
    }
    std::erase_if(retired_, [&](const std::unique_ptr<T>& old) {
      for (int r = 0; r < kReaders; ++r) {
        if (readers_[static_cast<std::size_t>(r)].mark.load(std::memory_order_seq_cst) ==
            old.get()) {
          return false;
        }
      }
      return true;
    });
  }

  /// Replaced values still held by a Read (not yet freed).
  std::size_t retired() const { return retired_.size(); }

 private:
  struct alignas(64) Reader {
    std::atomic<const T*> mark = nullptr;
  };
  std::unique_ptr<Reader[]> readers_;
  std::atomic<const T*> current_ = nullptr;  // owned_.get(), read without the lock
  std::unique_ptr<T> owned_;
  std::vector<std::unique_ptr<T>> retired_;
};

}  // namespace carat
