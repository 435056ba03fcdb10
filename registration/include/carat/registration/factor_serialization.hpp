#pragma once

/// A built registration factor as bytes, to move factors built by one process to the process
/// that solves (carat map under MPI): the kept block (block_serialization.hpp) with the factor's
/// correspondence count, bytes, times and model minimum, framed by a tag and a checksum. A factor
/// read back is equal to the one written, bit for bit.

#include <cstddef>
#include <span>
#include <string>
#include <vector>

#include "carat/registration/global_registration.hpp"

namespace carat {

/// The bytes of `factor` (its block's bytes plus 68). Throws carat::Error when the factor has
/// no block or its block has no byte form (full and random sampling keep GICP blocks and
/// compressed blocks over them, which have one; exact and lossless sampling are the ones meant
/// to be moved: a few KB each).
std::vector<std::byte> serialize_factor(const RegistrationFactor& factor);

/// The factor serialize_factor() wrote. Throws carat::Error starting with `what` for bytes that
/// are truncated, longer than a factor, fail the checksum or hold values no writer produces.
RegistrationFactor deserialize_factor(std::span<const std::byte> bytes, const std::string& what);

}  // namespace carat
