#include "cli_support.hpp"

#include <pthread.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <tbb/info.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <thread>

#include "carat/base/atomic_file.hpp"
#include "carat/base/output_folder.hpp"
#include "carat/base/temporary_paths.hpp"
#include "carat/registration/io/scan_folder.hpp"

namespace carat::cli {
namespace fs = std::filesystem;
namespace {

std::string number_text(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%g", value);
  return buffer;
}

/// The value as a user typed it, made safe for a message.
std::string shown(const std::string& value) { return quote_bytes(value); }

/// Parses a finite decimal number: digits, '.', an exponent; no hex, no inf/nan.
bool parse_real(const std::string& text, double* value) {
  if (text.empty()) return false;
  for (char c : text) {
    const bool ok =
        (c >= '0' && c <= '9') || c == '.' || c == 'e' || c == 'E' || c == '+' || c == '-';
    if (!ok) return false;
  }
  const char* first = text.data();
  if (*first == '+') ++first;
  const auto [ptr, ec] = std::from_chars(first, text.data() + text.size(), *value);
  return ec == std::errc() && ptr == text.data() + text.size() && std::isfinite(*value);
}

}  // namespace

CLI::Validator integer_in(long long min, long long max) {
  const std::string range = "[" + std::to_string(min) + ", " + std::to_string(max) + "]";
  return CLI::Validator(
      [min, max, range](std::string& value) -> std::string {
        const std::string problem = "must be an integer in " + range + ", got " + shown(value);
        if (value.empty()) return problem;
        const char* first = value.data();
        if (*first == '+') ++first;
        if (*first == '-' && min >= 0) return problem;
        long long parsed = 0;
        const auto [ptr, ec] = std::from_chars(first, value.data() + value.size(), parsed);
        if (ec != std::errc() || ptr != value.data() + value.size() || first == ptr) return problem;
        if (parsed < min || parsed > max) return problem;
        value = std::to_string(parsed);  // what CLI11 converts next: plain decimal
        return {};
      },
      "INT in " + range);
}

CLI::Validator seed_value() {
  return CLI::Validator(
      [](std::string& value) -> std::string {
        const std::string problem =
            "must be an integer in [0, 18446744073709551615], got " + shown(value);
        const char* first = value.data();
        if (!value.empty() && *first == '+') ++first;
        std::uint64_t parsed = 0;
        const auto [ptr, ec] = std::from_chars(first, value.data() + value.size(), parsed);
        if (value.empty() || ec != std::errc() || ptr != value.data() + value.size() ||
            first == ptr) {
          return problem;
        }
        value = std::to_string(parsed);
        return {};
      },
      "UINT64");
}

CLI::Validator real_in(double min, double max) {
  const std::string range = "[" + number_text(min) + ", " + number_text(max) + "]";
  return CLI::Validator(
      [min, max, range](std::string& value) -> std::string {
        double parsed = 0.0;
        if (!parse_real(value, &parsed) || parsed < min || parsed > max) {
          return "must be a finite number in " + range + ", got " + shown(value);
        }
        return {};
      },
      "NUMBER in " + range);
}

CLI::Validator zero_or_real_in(double min, double max, const std::string& zero_means) {
  const std::string range = "[" + number_text(min) + ", " + number_text(max) + "]";
  return CLI::Validator(
      [min, max, range, zero_means](std::string& value) -> std::string {
        double parsed = 0.0;
        if (!parse_real(value, &parsed) || (parsed != 0.0 && (parsed < min || parsed > max))) {
          return "must be 0 (" + zero_means + ") or a finite number in " + range + ", got " +
                 shown(value);
        }
        return {};
      },
      "0 or NUMBER in " + range);
}

CLI::Validator path_value() {
  return CLI::Validator(
      [](std::string& value) -> std::string {
        return value.empty() ? std::string("the path is empty") : std::string();
      },
      "PATH");
}

int thread_count(int requested) {
  const int cores = tbb::info::default_concurrency();
  return requested > 0 ? std::min(requested, cores) : cores;
}

void refuse_unused(const CLI::App& command, const std::string& option, bool applies,
                   const std::string& context) {
  if (!applies && command.count(option) > 0) {
    throw UsageError(option + " does not apply " + context);
  }
}

void check_output_file(const std::string& option, const std::string& path,
                       const std::vector<NamedInput>& inputs) {
  if (path.empty()) throw UsageError(option + ": the path is empty");
  fs::path target;
  try {
    target = resolve_output_path(path);
  } catch (const Error& e) {
    throw UsageError(option + " " + e.what());
  }
  struct stat s {};
  if (::stat(target.c_str(), &s) == 0) {
    if (S_ISDIR(s.st_mode)) throw UsageError(option + " " + path + ": is a directory, not a file");
    if (S_ISSOCK(s.st_mode)) throw UsageError(option + " " + path + ": is a socket, not a file");
  } else {
    const fs::path parent = target.parent_path().empty() ? fs::path(".") : target.parent_path();
    std::error_code ec;
    if (!fs::is_directory(parent, ec)) {
      throw UsageError(option + " " + path + ": the folder " + parent.string() + " does not exist");
    }
  }
  for (const NamedInput& input : inputs) {
    if (same_file(target, input.path)) {
      throw UsageError(option + " " + path + " is the same file as the input " + input.option +
                       " " + input.path + "; write the result elsewhere");
    }
  }
}

void check_output_folder(const std::string& option, const std::string& path,
                         const std::vector<NamedInput>& inputs) {
  if (path.empty()) throw UsageError(option + ": the path is empty");
  try {
    OutputFolder::check_target(path);
  } catch (const Error& e) {
    throw UsageError(option + " " + e.what());
  }
  std::error_code ec;
  const fs::path folder = fs::weakly_canonical(resolve_output_path(fs::absolute(path)), ec);
  if (ec) return;
  for (const NamedInput& input : inputs) {
    const fs::path inside = fs::weakly_canonical(fs::absolute(input.path), ec);
    if (ec) continue;
    const auto mismatch = std::mismatch(folder.begin(), folder.end(), inside.begin(), inside.end());
    if (mismatch.first == folder.end()) {
      throw UsageError(option + " " + path + " holds the input " + input.option + " " + input.path +
                       " and would be replaced; write the result elsewhere");
    }
  }
}

void check_output_outside_folder(const std::string& option, const std::string& path,
                                 const NamedInput& folder) {
  std::error_code ec;
  const fs::path inside = fs::canonical(folder.path, ec);
  if (ec || !fs::is_directory(inside, ec)) return;  // the reader names a missing folder
  fs::path target;
  try {
    target = fs::weakly_canonical(fs::absolute(resolve_output_path(path)), ec);
  } catch (const Error&) {
    return;  // check_output_file() / check_output_folder() name an unusable path
  }
  if (ec) return;
  const auto mismatch = std::mismatch(inside.begin(), inside.end(), target.begin(), target.end());
  if (mismatch.first != inside.end()) return;
  const std::string name = target.filename().string();
  if (looks_like_frame_name(name) || name == "points.bin") {
    throw UsageError(option + " " + path + " would become a frame of " + folder.option + " " +
                     folder.path + "; write the result elsewhere");
  }
  throw UsageError(option + " " + path + " lies inside " + folder.option + " " + folder.path +
                   ", a folder carat reads as input; write the result elsewhere");
}

std::uint64_t peak_rss_bytes() {
  rusage usage{};
  if (getrusage(RUSAGE_SELF, &usage) != 0) return 0;
  return static_cast<std::uint64_t>(usage.ru_maxrss) * 1024;  // kilobytes on Linux
}

std::uint64_t available_disk_bytes(const fs::path& path) {
  std::error_code ec;
  fs::path existing = fs::absolute(path, ec);
  while (!existing.empty() && !fs::exists(existing, ec)) existing = existing.parent_path();
  const fs::space_info space = fs::space(existing.empty() ? fs::path("/") : existing, ec);
  if (ec) return std::numeric_limits<std::uint64_t>::max();
  return space.available;
}

namespace {

[[noreturn]] void end_by_signal(int sig) {
  remove_temporaries_for_exit();
  // End the process by the same signal, as if it had not been caught.
  std::signal(sig, SIG_DFL);
  sigset_t one;
  sigemptyset(&one);
  sigaddset(&one, sig);
  pthread_sigmask(SIG_UNBLOCK, &one, nullptr);
  raise(sig);
  _exit(128 + sig);
}

}  // namespace

void install_interrupt_cleanup(int delay_ms) {
  sigset_t set;
  sigemptyset(&set);
  for (int sig :
       {SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGUSR1, SIGUSR2, SIGALRM, SIGPIPE, SIGXCPU, SIGXFSZ}) {
    sigaddset(&set, sig);
  }
  pthread_sigmask(SIG_BLOCK, &set, nullptr);
  std::thread([set, delay_ms] {
    int sig = 0;
    while (sigwait(&set, &sig) != 0) {
    }
    if (delay_ms > 0) std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms));
    end_by_signal(sig);
  }).detach();
}

void flush_standard_output() {
  errno = 0;
  if (std::fflush(stdout) == 0 && std::ferror(stdout) == 0) return;
  const int error = errno;
  if (error == EPIPE) end_by_signal(SIGPIPE);  // the reader went away: end as a pipeline does
  throw Error(std::string("cannot write the output to standard output") +
              (error != 0 ? std::string(": ") + std::strerror(error) : std::string()) +
              "; no output was written");
}

int finish_standard_output(int status) {
  errno = 0;
  const bool failed = std::fflush(stdout) != 0 || std::ferror(stdout) != 0;
  if (!failed || status != 0) return status;  // a failed run has said why already
  const int error = errno;
  if (error == EPIPE) end_by_signal(SIGPIPE);
  std::fprintf(stderr, "carat: error: cannot write the output to standard output%s%s\n",
               error != 0 ? ": " : "", error != 0 ? std::strerror(error) : "");
  return 1;
}

}  // namespace carat::cli
