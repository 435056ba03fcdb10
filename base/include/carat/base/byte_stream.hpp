#pragma once

/// Values written to and read back from a flat byte buffer (to send objects between processes of
/// one job: the bytes are in the machine's own byte order and layout). The reader checks every
/// length against what is left, so truncated or garbled input is an error, never a read past
/// the end.

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "carat/base/error.hpp"

namespace carat {

/// FNV-1a 64-bit hash of `bytes` (a checksum against garbled transfers, not a cryptographic one).
std::uint64_t fnv1a_checksum(std::span<const std::byte> bytes);

/// Appends trivially copyable values and arrays of them to a byte buffer.
class ByteWriter {
 public:
  /// Appends to `out` (kept by reference; it must outlive the writer).
  explicit ByteWriter(std::vector<std::byte>& out) : out_(out) {}

  /// Appends one value's bytes.
  template <typename T>
  void put(const T& value) {
    static_assert(std::is_trivially_copyable_v<T>);
    append(&value, sizeof(T));
  }
  /// Appends the values' bytes (no count: write one first when the reader needs it).
  template <typename T>
  void put_array(std::span<const T> values) {
    static_assert(std::is_trivially_copyable_v<T>);
    append(values.data(), values.size_bytes());
  }
  /// Appends a length (std::uint64_t) and the string's bytes.
  void put_string(const std::string& text);
  /// Bytes in the buffer so far.
  std::size_t size() const { return out_.size(); }

 private:
  void append(const void* data, std::size_t size);

  std::vector<std::byte>& out_;
};

/// Reads values back in the order a ByteWriter wrote them. Every read throws carat::Error
/// ("<what>: truncated ...") when fewer bytes are left than it needs.
class ByteReader {
 public:
  /// Reads `bytes` (not copied; they must outlive the reader); `what` names them in errors.
  ByteReader(std::span<const std::byte> bytes, std::string what)
      : bytes_(bytes), what_(std::move(what)) {}

  /// The next value.
  template <typename T>
  T get() {
    static_assert(std::is_trivially_copyable_v<T>);
    T value;
    std::memcpy(&value, take(sizeof(T)), sizeof(T));
    return value;
  }
  /// The next `count` values (the count is checked against the bytes left before anything is
  /// allocated).
  template <typename T>
  std::vector<T> get_array(std::size_t count) {
    static_assert(std::is_trivially_copyable_v<T>);
    if (count > remaining() / sizeof(T)) truncated(count, sizeof(T));
    std::vector<T> values(count);
    if (count > 0) std::memcpy(values.data(), take(count * sizeof(T)), count * sizeof(T));
    return values;
  }
  /// A string written by ByteWriter::put_string().
  std::string get_string();
  /// The next `count` bytes as a view into the input.
  std::span<const std::byte> get_bytes(std::size_t count);
  /// Bytes not read yet.
  std::size_t remaining() const { return bytes_.size() - offset_; }
  /// Bytes read so far.
  std::size_t offset() const { return offset_; }
  /// Throws carat::Error ("<what>: ... trailing bytes") unless every byte was read.
  void expect_end() const;
  /// Throws carat::Error "<what>: garbled: <why>" (for a value that fails a check).
  [[noreturn]] void garbled(const std::string& why) const;
  /// The name given to the constructor.
  const std::string& what() const { return what_; }

 private:
  const std::byte* take(std::size_t count);
  [[noreturn]] void truncated(std::size_t count, std::size_t size) const;

  std::span<const std::byte> bytes_;
  std::size_t offset_ = 0;
  std::string what_;
};

}  // namespace carat
