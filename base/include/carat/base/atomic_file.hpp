#pragma once

/// How carat writes an output file, so that the path ends either complete or untouched:
/// - a new path or an existing regular file: the content goes to a temporary file beside it
///   (a hidden name that fits NAME_MAX, registered in temporary_paths.hpp), which is renamed over
///   the path only when everything was written; an existing file keeps its permission bits (and,
///   where allowed, its owner). A hard link to the old file keeps the old content.
/// - a symbolic link is followed: the file it points to is replaced, the link stays.
/// - an existing character device or FIFO (/dev/null, a named pipe) is written through, never
///   replaced; so is a descriptor of this process (/dev/stdout, /dev/stderr, /dev/fd/N,
///   /proc/self/fd/N), written at its current offset after what the process printed there.
/// - a directory or a socket is an error.

#include <filesystem>
#include <functional>
#include <memory>
#include <ostream>

namespace carat {

/// An output file written in two phases: fill stream(), then commit() puts it in place by the
/// rules above. Destroyed without commit() (an error, an exception), it leaves the path
/// untouched and removes its temporary file.
class OutputFile {
 public:
  /// Prepares the output `path` (links followed). Throws carat::Error naming it when it is a
  /// directory or a socket, its folder does not exist, or a temporary cannot be created.
  explicit OutputFile(const std::filesystem::path& path);
  ~OutputFile();
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  /// Where to write the content.
  std::ostream& stream();
  /// Moves the content into place (or writes it through the device). Throws carat::Error naming
  /// the path when a write fails; then the path is untouched (a device may hold part of it).
  void commit();

 private:
  struct State;
  std::unique_ptr<State> state_;
};

/// Writes the output `path` as above: calls `write` with a stream on the temporary file (or on
/// the device), then moves it into place. If `write` throws or a write fails, the temporary file
/// is removed, `path` is untouched, and carat::Error naming the path is thrown.
void write_file_atomically(const std::filesystem::path& path,
                           const std::function<void(std::ostream&)>& write);

/// `path` with its symbolic links followed to the file or folder they name (which may not exist
/// yet); throws carat::Error naming `path` for a loop of links.
std::filesystem::path resolve_output_path(const std::filesystem::path& path);

/// Whether `a` and `b` name the same existing file or folder (after links; false when either is
/// missing). Used to refuse an output that would replace an input.
bool same_file(const std::filesystem::path& a, const std::filesystem::path& b);

}  // namespace carat
