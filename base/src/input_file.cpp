#include "carat/base/input_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "carat/base/error.hpp"

namespace carat {
namespace {

std::string describe(mode_t mode) {
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

constexpr std::size_t kChunkBytes = std::size_t{1} << 20;

}  // namespace

InputFile::InputFile(const std::filesystem::path& path, InputKind kind) : name_(path.string()) {
  struct stat before {};
  if (::stat(name_.c_str(), &before) != 0) {
    const int error = errno;
    if (error == ENOENT || error == ENOTDIR) throw Error(name_ + ": no such file");
    throw Error(name_ + ": cannot read: " + std::strerror(error));
  }
  if (S_ISDIR(before.st_mode)) throw Error(name_ + ": is a directory, not a file");
  if (S_ISSOCK(before.st_mode)) throw Error(name_ + ": is a socket, not a file");
  if (kind == InputKind::kRegular && !S_ISREG(before.st_mode)) {
    throw Error(name_ + ": is " + describe(before.st_mode) +
                ", not a regular file (this input is read from regular files only)");
  }
  do {
    fd_ = ::open(name_.c_str(), O_RDONLY | O_CLOEXEC);
  } while (fd_ < 0 && errno == EINTR);
  if (fd_ < 0) throw Error(name_ + ": cannot open for reading: " + std::strerror(errno));
  struct stat opened {};
  if (::fstat(fd_, &opened) != 0 || (opened.st_mode & S_IFMT) != (before.st_mode & S_IFMT)) {
    ::close(fd_);
    throw Error(name_ + ": changed while it was opened");
  }
  if (S_ISREG(opened.st_mode)) size_ = static_cast<std::uint64_t>(opened.st_size);
}

InputFile::~InputFile() {
  if (fd_ >= 0) ::close(fd_);
}

std::size_t InputFile::read(char* out, std::size_t n) {
  n = std::min(n, kChunkBytes);
  for (;;) {
    const ssize_t got = ::read(fd_, out, n);
    if (got >= 0) {
      consumed_ += static_cast<std::uint64_t>(got);
      return static_cast<std::size_t>(got);
    }
    if (errno != EINTR) throw Error(name_ + ": read error: " + std::strerror(errno));
  }
}

std::optional<std::uint64_t> InputFile::remaining() const {
  if (!size_) return std::nullopt;
  return *size_ > consumed_ ? *size_ - consumed_ : 0;
}

std::size_t MemorySource::read(char* out, std::size_t n) {
  const std::size_t count = std::min(n, bytes_.size() - position_);
  std::memcpy(out, bytes_.data() + position_, count);
  position_ += count;
  return count;
}

LineReader::LineReader(ByteSource& source, std::size_t max_line_bytes)
    : source_(source), max_line_bytes_(std::max<std::size_t>(max_line_bytes, 1)) {}

bool LineReader::fill() {
  if (at_end_) return false;
  if (begin_ > 0) {  // keep the unread bytes at the front
    std::memmove(buffer_.data(), buffer_.data() + begin_, end_ - begin_);
    end_ -= begin_;
    begin_ = 0;
  }
  const std::size_t want = std::max<std::size_t>(std::min(max_line_bytes_ + 2, kChunkBytes), 4096);
  if (buffer_.size() < end_ + want) buffer_.resize(end_ + want);
  const std::size_t got = source_.read(buffer_.data() + end_, buffer_.size() - end_);
  if (got == 0) {
    at_end_ = true;
    return false;
  }
  end_ += got;
  return true;
}

bool LineReader::next_line(std::string_view* line) {
  std::size_t scanned = 0;  // bytes after begin_ already searched for '\n'
  for (;;) {
    const std::size_t available = end_ - begin_;
    const char* text = buffer_.data() + begin_;
    const void* newline =
        available > scanned ? std::memchr(text + scanned, '\n', available - scanned) : nullptr;
    std::size_t length = available;
    if (newline != nullptr) {
      length = static_cast<std::size_t>(static_cast<const char*>(newline) - text);
    } else {
      // No line end yet: a NUL byte or an over-long line is refused before reading more.
      if (available > scanned && std::memchr(text + scanned, '\0', available - scanned)) {
        throw Error(source_.name() + ":" + std::to_string(line_number_ + 1) +
                    ": holds a NUL byte (a binary file?)");
      }
      if (available <= max_line_bytes_) {
        scanned = available;
        if (fill()) continue;  // fill() keeps the unread bytes at the front: `scanned` holds
        if (available == 0) return false;
      }
    }
    if (length > max_line_bytes_) {
      throw Error(source_.name() + ":" + std::to_string(line_number_ + 1) +
                  ": line is longer than " + std::to_string(max_line_bytes_) +
                  " bytes (not a text file of this format?)");
    }
    text = buffer_.data() + begin_;
    ++line_number_;
    if (std::memchr(text, '\0', length) != nullptr) {
      throw Error(source_.name() + ":" + std::to_string(line_number_) +
                  ": holds a NUL byte (a binary file?)");
    }
    begin_ += length + (newline != nullptr ? 1 : 0);
    if (length > 0 && text[length - 1] == '\r') --length;
    *line = std::string_view(text, length);
    return true;
  }
}

std::size_t LineReader::read(char* out, std::size_t n) {
  std::size_t done = 0;
  const std::size_t buffered = std::min(n, end_ - begin_);
  std::memcpy(out, buffer_.data() + begin_, buffered);
  begin_ += buffered;
  done += buffered;
  while (done < n) {
    const std::size_t got = source_.read(out + done, n - done);
    if (got == 0) break;
    done += got;
  }
  return done;
}

std::optional<std::uint64_t> LineReader::remaining() const {
  const auto left = source_.remaining();
  if (!left) return std::nullopt;
  return *left + (end_ - begin_);
}

}  // namespace carat
