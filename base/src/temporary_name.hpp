#pragma once

#include <filesystem>
#include <string>
#include <string_view>

namespace carat::internal {

/// A hidden, unique-looking name for a temporary beside `target`: "." + target's name + "." +
/// `kind` + "-" + 12 hex digits, with target's name shortened so the whole fits NAME_MAX.
std::string temporary_name(const std::filesystem::path& target, std::string_view kind);

}  // namespace carat::internal
