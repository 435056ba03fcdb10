#include "carat/registration/factor_serialization.hpp"

#include <cmath>
#include <cstdint>
#include <cstring>

#include "carat/base/byte_stream.hpp"
#include "carat/base/error.hpp"
#include "carat/residuals/block_serialization.hpp"

namespace carat {
namespace {

constexpr std::uint32_t kFactorTag = 0x31465243;  // "CRF1" in little-endian byte order

}  // namespace

std::vector<std::byte> serialize_factor(const RegistrationFactor& factor) {
  if (!factor.block) throw Error("serialize_factor: the factor has no block");
  std::vector<std::byte> bytes;
  ByteWriter out(bytes);
  out.put(kFactorTag);
  out.put(std::uint64_t{0});  // the whole length, set below
  write_block(*factor.block, out);
  out.put(static_cast<std::uint64_t>(factor.correspondences));
  out.put(static_cast<std::uint64_t>(factor.correspondence_bytes));
  out.put(factor.correspondence_s);
  out.put(factor.compression_s);
  out.put(factor.minimum_s);
  out.put(factor.minimum);
  const auto length = static_cast<std::uint64_t>(bytes.size() + sizeof(std::uint64_t));
  std::memcpy(bytes.data() + sizeof(kFactorTag), &length, sizeof(length));
  out.put(fnv1a_checksum(bytes));
  return bytes;
}

RegistrationFactor deserialize_factor(std::span<const std::byte> bytes, const std::string& what) {
  ByteReader in(bytes, what);
  if (in.get<std::uint32_t>() != kFactorTag)
    in.garbled("not a registration factor (its tag is wrong)");
  const auto length = in.get<std::uint64_t>();
  if (length != bytes.size()) {
    throw Error(what + (length > bytes.size() ? ": truncated: " : ": garbled: ") +
                std::to_string(bytes.size()) + " bytes for a factor of " + std::to_string(length));
  }
  const std::span<const std::byte> body = bytes.first(bytes.size() - sizeof(std::uint64_t));
  std::uint64_t stored = 0;
  std::memcpy(&stored, bytes.data() + body.size(), sizeof(stored));
  if (stored != fnv1a_checksum(body)) throw Error(what + ": garbled: the checksum does not match");
  RegistrationFactor factor;
  factor.block = read_block(in);
  factor.correspondences = static_cast<std::size_t>(in.get<std::uint64_t>());
  factor.correspondence_bytes = static_cast<std::size_t>(in.get<std::uint64_t>());
  factor.correspondence_s = in.get<double>();
  factor.compression_s = in.get<double>();
  factor.minimum_s = in.get<double>();
  factor.minimum = in.get<double>();
  in.get<std::uint64_t>();  // the checksum, tested above
  in.expect_end();
  if (!std::isfinite(factor.minimum) || factor.minimum < 0.0)
    in.garbled("a factor minimum that is negative or not finite");
  return factor;
}

}  // namespace carat
