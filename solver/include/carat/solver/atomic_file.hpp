#pragma once

/// Output files that are never left half-written: content goes to a temporary file beside the
/// destination, which is renamed over it only when everything was written.

#include <filesystem>
#include <functional>
#include <ostream>

namespace carat {

/// Calls `write` with a stream on a temporary file next to `path`, then renames it to `path`.
/// If `write` throws or the stream fails, the temporary file is removed, `path` is untouched,
/// and carat::Error (naming the path) is thrown.
void write_file_atomically(const std::filesystem::path& path,
                           const std::function<void(std::ostream&)>& write);

}  // namespace carat
