#pragma once

// What every carat subcommand shares: option validators that refuse what a range check lets
// through (NaN, Inf, signs on unsigned numbers, wrap-around, hex), usage errors raised after
// parsing, checks of output paths against the inputs, the interruption cleanup, the final check
// of standard output, and what the machine has (memory, disk).

#include <CLI/CLI.hpp>
#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/base/machine_memory.hpp"

namespace carat::cli {

/// A usage error found after parsing (a combination of options, an output that would replace an
/// input, a size the machine cannot hold): main() prints it as one line and exits with 2.
class UsageError : public Error {
 public:
  /// `message` names the option(s) and the problem.
  explicit UsageError(const std::string& message) : Error(message) {}
};

/// A decimal integer in [min, max]: no sign unless min < 0, no hex, no exponent, no wrap-around.
CLI::Validator integer_in(long long min, long long max);
/// A seed: a decimal integer in [0, 2^64 - 1] (no sign, no wrap-around).
CLI::Validator seed_value();
/// A finite decimal number in [min, max] (NaN and Inf refused).
CLI::Validator real_in(double min, double max);
/// 0 (which means `zero_means`, "off" unless given), or a finite number in [min, max].
CLI::Validator zero_or_real_in(double min, double max, const std::string& zero_means = "off");
/// A path: not empty.
CLI::Validator path_value();

/// Threads to use: `requested` (0: all cores), at most the cores TBB may use.
int thread_count(int requested);

/// Refuses `option` when it was given (count > 0) although `why_not` holds: a usage error
/// "`option` does not apply `why_not`" (e.g. "--sampling does not apply to --method pgo").
void refuse_unused(const CLI::App& command, const std::string& option, bool applies,
                   const std::string& context);

/// An input named on the command line: the option (or "FILE") and the path.
struct NamedInput {
  std::string option;  ///< e.g. "--poses"
  std::string path;    ///< as given
};

/// Checks an output file option before any work: the path is not a directory or a socket, its
/// folder exists, and it is not the same file as any input. Throws UsageError naming the option.
void check_output_file(const std::string& option, const std::string& path,
                       const std::vector<NamedInput>& inputs);

/// Checks an output folder option before any work (OutputFolder::check_target) and that no input
/// lies inside it (it is replaced as a whole). Throws UsageError naming the option.
void check_output_folder(const std::string& option, const std::string& path,
                         const std::vector<NamedInput>& inputs);

/// Checks an output file or folder option against an input folder of frames (or of data sets)
/// before any work: the output must not lie inside it, at any depth and through links, where a
/// later run would read it as a frame or find it among the frames. Throws UsageError naming both.
void check_output_outside_folder(const std::string& option, const std::string& path,
                                 const NamedInput& folder);

/// Bytes free for an unprivileged writer on the file system that holds `path` (or its nearest
/// existing parent).
std::uint64_t available_disk_bytes(const std::filesystem::path& path);
/// The largest resident set this process has had so far, bytes (getrusage's ru_maxrss).
std::uint64_t peak_rss_bytes();

/// Blocks the signals that end a process by default and can be caught (SIGINT, SIGTERM, SIGHUP,
/// SIGQUIT, SIGUSR1, SIGUSR2, SIGALRM, SIGPIPE, SIGXCPU, SIGXFSZ) in the calling thread (so in
/// every thread started after) and starts a thread that, when one arrives, removes carat's
/// temporary files and folders and ends the process by that signal. Call first thing in main().
/// `delay_ms` postpones the cleanup and the end: a rank other than 0 of an mpirun job, which
/// holds no output, passes one so that rank 0 has removed its temporaries before mpirun, seeing
/// a rank end by a signal, kills every rank with SIGKILL (as it does at once).
void install_interrupt_cleanup(int delay_ms = 0);

/// Flushes standard output before outputs are committed: throws carat::Error if a write to it
/// failed (a full disk), so that the run ends without replacing its outputs; a closed pipe
/// (EPIPE) ends the process by SIGPIPE after removing the temporaries, as a pipeline expects.
void flush_standard_output();

/// Flushes standard output at exit; if that or any earlier write to it failed, prints one line
/// on stderr and returns 1, else returns `status`.
int finish_standard_output(int status);

}  // namespace carat::cli
