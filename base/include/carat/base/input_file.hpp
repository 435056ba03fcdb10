#pragma once

/// Bounded reading of carat's inputs: a file is checked before it is read (what it is, how large),
/// and read in chunks; text is read line by line with a bound on the line length, so that no input
/// (a device, a FIFO, a file with no line breaks) makes a reader allocate without bound.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace carat {

/// The bytes of one input, read in pieces.
class ByteSource {
 public:
  virtual ~ByteSource() = default;
  /// Copies up to `n` bytes to `out` and returns how many (0 only at the end). Throws
  /// carat::Error naming the input on a read error.
  virtual std::size_t read(char* out, std::size_t n) = 0;
  /// Bytes left when that is known (a regular file or memory); nullopt for a FIFO or a device.
  virtual std::optional<std::uint64_t> remaining() const = 0;
  /// The input's name for messages: the path, or the name given to a MemorySource.
  virtual const std::string& name() const = 0;
};

/// Which kinds of file an InputFile accepts.
enum class InputKind {
  kRegular,     ///< regular files only: binary data whose size is checked before it is read
  kStreamable,  ///< also FIFOs and devices (text read line by line, e.g. `<(command)`)
};

/// A file opened for reading after its kind was checked (symbolic links are followed).
class InputFile final : public ByteSource {
 public:
  /// Opens `path`. Throws carat::Error naming it when it does not exist ("no such file"), is a
  /// directory, a socket, not a regular file while `kind` is kRegular, or cannot be opened.
  InputFile(const std::filesystem::path& path, InputKind kind);
  ~InputFile() override;
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;

  std::size_t read(char* out, std::size_t n) override;
  std::optional<std::uint64_t> remaining() const override;
  const std::string& name() const override { return name_; }
  /// Size in bytes of a regular file when it was opened; nullopt for FIFOs and devices.
  std::optional<std::uint64_t> size() const { return size_; }

 private:
  std::string name_;
  int fd_ = -1;
  std::optional<std::uint64_t> size_;
  std::uint64_t consumed_ = 0;
};

/// Bytes held in memory, read like a file (for parsers of in-memory text and for fuzzers).
class MemorySource final : public ByteSource {
 public:
  /// Reads `bytes` (which must outlive the source); `name` is used in messages.
  MemorySource(std::string_view bytes, std::string name) : bytes_(bytes), name_(std::move(name)) {}
  std::size_t read(char* out, std::size_t n) override;
  std::optional<std::uint64_t> remaining() const override { return bytes_.size() - position_; }
  const std::string& name() const override { return name_; }

 private:
  std::string_view bytes_;
  std::string name_;
  std::size_t position_ = 0;
};

/// Lines, then optionally raw bytes, of a ByteSource, through one buffer. A line may not be longer
/// than a bound nor hold a NUL byte, so a binary file or a device is refused at its first line.
class LineReader {
 public:
  /// Longest line accepted by default, in bytes (carat's text formats have lines under 1 KiB).
  static constexpr std::size_t kDefaultMaxLineBytes = 65536;

  /// Reads `source` (which must outlive the reader).
  explicit LineReader(ByteSource& source, std::size_t max_line_bytes = kDefaultMaxLineBytes);

  /// The next line without its '\n' (and a trailing '\r'); false at the end of the input. The
  /// view is valid until the next call. Throws carat::Error "NAME:LINE: ..." for a line longer
  /// than the bound or one that holds a NUL byte.
  bool next_line(std::string_view* line);
  /// The number (from 1) of the line next_line() returned last.
  std::size_t line_number() const { return line_number_; }
  /// Copies up to `n` raw bytes that follow the lines read so far; returns how many (fewer only
  /// at the end of the input).
  std::size_t read(char* out, std::size_t n);
  /// Bytes after those read so far, when the source knows its size.
  std::optional<std::uint64_t> remaining() const;
  /// The input's name for messages.
  const std::string& name() const { return source_.name(); }

 private:
  bool fill();  // reads more into the buffer; false at the end of the input

  ByteSource& source_;
  std::size_t max_line_bytes_;
  std::vector<char> buffer_;
  std::size_t begin_ = 0;  // first unread byte in buffer_
  std::size_t end_ = 0;    // one past the last valid byte in buffer_
  bool at_end_ = false;
  std::size_t line_number_ = 0;
};

}  // namespace carat
