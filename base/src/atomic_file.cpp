#include "carat/base/atomic_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <system_error>

#include "carat/base/error.hpp"
#include "carat/base/temporary_paths.hpp"
#include "temporary_name.hpp"

namespace carat {
namespace fs = std::filesystem;

namespace internal {

std::string temporary_name(const fs::path& target, std::string_view kind) {
  static std::atomic<std::uint64_t> counter{0};
  static const std::uint64_t base = [] {
    std::random_device device;
    return (static_cast<std::uint64_t>(device()) << 32) ^ device();
  }();
  const std::uint64_t value = base + 0x9e3779b97f4a7c15ULL * ++counter;
  char suffix[40];
  std::snprintf(suffix, sizeof(suffix), ".%.*s-%012llx", static_cast<int>(kind.size()), kind.data(),
                static_cast<unsigned long long>(value & 0xffffffffffffULL));
  // "." + name + suffix must fit NAME_MAX (255 bytes): shorten the name part when needed.
  constexpr std::size_t kNameMax = 255;
  std::string name = target.filename().string();
  const std::size_t room = kNameMax - 1 - std::strlen(suffix);
  if (name.size() > room) name.resize(room);
  return "." + name + suffix;
}

}  // namespace internal

namespace {

/// The descriptor a path names when it is one of this process's (/dev/stdout, /dev/stderr,
/// /dev/fd/N, /proc/self/fd/N, /proc/<pid>/fd/N), directly or through links.
std::optional<int> own_descriptor(const fs::path& path) {
  const auto number = [](std::string_view text) -> std::optional<int> {
    int fd = -1;
    const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), fd);
    if (ec != std::errc() || ptr != text.data() + text.size() || fd < 0) return std::nullopt;
    return fd;
  };
  const std::string own_proc = "/proc/" + std::to_string(::getpid()) + "/fd/";
  fs::path current = path;
  for (int hops = 0; hops < 40; ++hops) {
    const std::string text = current.lexically_normal().string();
    if (text == "/dev/stdout") return 1;
    if (text == "/dev/stderr") return 2;
    for (const std::string& prefix :
         {std::string("/dev/fd/"), std::string("/proc/self/fd/"), own_proc}) {
      if (text.rfind(prefix, 0) == 0) return number(std::string_view(text).substr(prefix.size()));
    }
    std::error_code ec;
    if (!fs::is_symlink(fs::symlink_status(current, ec))) return std::nullopt;
    const fs::path target = fs::read_symlink(current, ec);
    if (ec) return std::nullopt;
    current = target.is_absolute() ? target : current.parent_path() / target;
  }
  return std::nullopt;
}

void write_all(int fd, const std::string& bytes, const std::string& name) {
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) throw Error(name + ": write failed: " + std::strerror(errno));
    done += static_cast<std::size_t>(n);
  }
}

}  // namespace

fs::path resolve_output_path(const fs::path& path) {
  fs::path current = path;
  for (int hops = 0; hops < 40; ++hops) {
    std::error_code ec;
    const fs::file_status status = fs::symlink_status(current, ec);
    if (ec || !fs::is_symlink(status)) return current;
    const fs::path target = fs::read_symlink(current, ec);
    if (ec) throw Error(path.string() + ": cannot read the symbolic link: " + ec.message());
    current = target.is_absolute() ? target : current.parent_path() / target;
  }
  throw Error(path.string() + ": too many levels of symbolic links");
}

bool same_file(const fs::path& a, const fs::path& b) {
  std::error_code ec;
  const bool same = fs::equivalent(a, b, ec);
  return !ec && same;
}

struct OutputFile::State {
  enum class Mode { kReplace, kThrough, kDescriptor };
  Mode mode = Mode::kReplace;
  std::string name;
  fs::path target;
  fs::path temporary;
  int descriptor = -1;
  std::ofstream file;
  std::ostringstream buffer;
  bool committed = false;
};

OutputFile::OutputFile(const fs::path& path) : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.name = path.string();
  if (const std::optional<int> fd = own_descriptor(path)) {
    s.mode = State::Mode::kDescriptor;
    s.descriptor = *fd;
    if (::fcntl(*fd, F_GETFD) < 0)
      throw Error(s.name + ": descriptor " + std::to_string(*fd) + " is not open");
    return;
  }
  s.target = resolve_output_path(path);
  struct stat existing {};
  const bool exists = ::stat(s.target.c_str(), &existing) == 0;
  if (exists && S_ISDIR(existing.st_mode)) throw Error(s.name + ": is a directory, not a file");
  if (exists && S_ISSOCK(existing.st_mode)) throw Error(s.name + ": is a socket, not a file");
  if (exists && !S_ISREG(existing.st_mode)) {
    s.mode = State::Mode::kThrough;  // a device or a FIFO: written through at commit()
    return;
  }
  const fs::path dir = s.target.parent_path();
  s.temporary = create_temporary([&] {
    for (int attempt = 0;; ++attempt) {
      const fs::path candidate = dir / internal::temporary_name(s.target, "tmp");
      const int fd = ::open(candidate.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
      if (fd >= 0) {
        if (exists) {
          // Keep the replaced file's permission bits and, where allowed, its owner.
          if (::fchown(fd, existing.st_uid, existing.st_gid) != 0) {
            // Not permitted (not root): the new file belongs to whoever runs carat.
          }
          (void)::fchmod(fd, existing.st_mode & 07777);
        }
        ::close(fd);
        return candidate;
      }
      if (errno != EEXIST || attempt >= 100) {
        throw Error(s.name + ": cannot create a file in " + (dir.empty() ? "." : dir.string()) +
                    ": " + std::strerror(errno));
      }
    }
  });
  s.file.open(s.temporary, std::ios::binary | std::ios::trunc);
  if (!s.file) {
    const int error = errno;
    release_temporary(s.temporary, [&] {
      std::error_code ignored;
      fs::remove(s.temporary, ignored);
    });
    throw Error(s.name + ": cannot open for writing: " + std::strerror(error));
  }
}

OutputFile::~OutputFile() {
  State& s = *state_;
  if (s.committed || s.mode != State::Mode::kReplace) return;
  s.file.close();
  release_temporary(s.temporary, [&] {
    std::error_code ignored;
    fs::remove(s.temporary, ignored);
  });
}

std::ostream& OutputFile::stream() {
  State& s = *state_;
  if (s.mode == State::Mode::kReplace) return s.file;
  return s.buffer;
}

void OutputFile::commit() {
  State& s = *state_;
  if (s.committed) throw Error(s.name + ": the output was committed already");
  switch (s.mode) {
    case State::Mode::kDescriptor:
      if (s.descriptor == 1) std::fflush(stdout);
      if (s.descriptor == 2) std::fflush(stderr);
      write_all(s.descriptor, s.buffer.str(), s.name);
      break;
    case State::Mode::kThrough: {
      int fd = -1;
      do {
        fd = ::open(s.target.c_str(), O_WRONLY | O_CLOEXEC);
      } while (fd < 0 && errno == EINTR);
      if (fd < 0) throw Error(s.name + ": cannot open for writing: " + std::strerror(errno));
      try {
        write_all(fd, s.buffer.str(), s.name);
      } catch (...) {
        ::close(fd);
        throw;
      }
      ::close(fd);
      break;
    }
    case State::Mode::kReplace: {
      s.file.flush();
      if (!s.file) throw Error(s.name + ": write failed: " + std::strerror(errno));
      s.file.close();
      if (!s.file) throw Error(s.name + ": write failed: " + std::strerror(errno));
      release_temporary(s.temporary, [&] {
        std::error_code ec;
        fs::rename(s.temporary, s.target, ec);
        if (ec) {
          std::error_code ignored;
          fs::remove(s.temporary, ignored);
          throw Error(s.name + ": cannot move the finished file into place: " + ec.message());
        }
      });
      break;
    }
  }
  s.committed = true;
}

void write_file_atomically(const fs::path& path, const std::function<void(std::ostream&)>& write) {
  OutputFile file(path);
  write(file.stream());
  file.commit();
}

}  // namespace carat
