#include "carat/base/byte_stream.hpp"

namespace carat {

std::uint64_t fnv1a_checksum(std::span<const std::byte> bytes) {
  std::uint64_t hash = 0xcbf29ce484222325ULL;
  for (const std::byte b : bytes) {
    hash ^= static_cast<std::uint64_t>(b);
    hash *= 0x100000001b3ULL;
  }
  return hash;
}

void ByteWriter::append(const void* data, std::size_t size) {
  if (size == 0) return;
  const std::size_t at = out_.size();
  out_.resize(at + size);
  std::memcpy(out_.data() + at, data, size);
}

void ByteWriter::put_string(const std::string& text) {
  put(static_cast<std::uint64_t>(text.size()));
  put_array(std::span<const char>(text.data(), text.size()));
}

std::string ByteReader::get_string() {
  const auto length = get<std::uint64_t>();
  if (length > remaining()) truncated(static_cast<std::size_t>(length), 1);
  const std::byte* p = take(static_cast<std::size_t>(length));
  return std::string(reinterpret_cast<const char*>(p), static_cast<std::size_t>(length));
}

std::span<const std::byte> ByteReader::get_bytes(std::size_t count) {
  if (count > remaining()) truncated(count, 1);
  return {take(count), count};
}

void ByteReader::expect_end() const {
  if (remaining() != 0)
    throw Error(what_ + ": garbled: " + std::to_string(remaining()) + " trailing bytes after " +
                std::to_string(offset_));
}

void ByteReader::garbled(const std::string& why) const {
  throw Error(what_ + ": garbled: " + why + " (at byte " + std::to_string(offset_) + " of " +
              std::to_string(bytes_.size()) + ")");
}

const std::byte* ByteReader::take(std::size_t count) {
  if (count > remaining()) truncated(count, 1);
  const std::byte* p = bytes_.data() + offset_;
  offset_ += count;
  return p;
}

void ByteReader::truncated(std::size_t count, std::size_t size) const {
  throw Error(what_ + ": truncated: " + std::to_string(count) + " x " + std::to_string(size) +
              " bytes needed at byte " + std::to_string(offset_) + ", " +
              std::to_string(remaining()) + " left");
}

}  // namespace carat
