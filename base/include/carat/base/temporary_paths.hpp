#pragma once

/// The temporary files and folders that carat's writers are filling, in one process-wide list,
/// so that a program can remove them when it is interrupted: the carat command-line tool does so
/// on SIGINT, SIGTERM and SIGHUP. Library code only registers and releases; it installs no
/// signal handlers.

#include <filesystem>
#include <functional>

namespace carat {

/// Calls `create` (which makes a temporary file or folder and returns its path) and registers the
/// path, both under the list's lock, so that an interruption never misses a path that exists.
std::filesystem::path create_temporary(const std::function<std::filesystem::path()>& create);

/// Calls `finish` (e.g. the rename that moves a finished file into place, or the removal of a
/// failed one) and forgets `path`, both under the list's lock. Exceptions from `finish` propagate
/// after `path` was forgotten.
void release_temporary(const std::filesystem::path& path, const std::function<void()>& finish);

/// Removes every registered path (folders with their contents) and keeps the list locked for good,
/// so that no other thread creates or moves a temporary afterwards. Call it only when the process
/// is about to end (the CLI's signal thread does); never throws.
void remove_temporaries_for_exit() noexcept;

}  // namespace carat
