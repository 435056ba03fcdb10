// Inputs and outputs: bounded line reading, the kinds of input file, and the output contract
// (atomic files that keep their mode, links followed, devices and FIFOs written through, output
// folders that are complete or absent, temporaries removed on interruption).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "carat/base/atomic_file.hpp"
#include "carat/base/error.hpp"
#include "carat/base/input_file.hpp"
#include "carat/base/output_folder.hpp"
#include "carat/base/temporary_paths.hpp"
#include "test_support.hpp"

namespace carat {
namespace {

namespace fs = std::filesystem;

using test::error_of;

std::string read_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

std::vector<std::string> names_in(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir)) names.push_back(entry.path().filename());
  std::sort(names.begin(), names.end());
  return names;
}

TEST(QuoteBytesTest, KeepsMessagesShortAndPrintable) {
  EXPECT_EQ(quote_bytes("abc"), "'abc'");
  EXPECT_EQ(quote_bytes(std::string("a\0b\n\x7f\xff", 6)), "'a?b?\?\?'");
  EXPECT_EQ(quote_bytes(std::string(100, 'x')), "'" + std::string(40, 'x') + "...'");
}

TEST(LineReaderTest, LinesEndingsAndRawBytesAfterThem) {
  const std::string text = "first\r\nsecond\n\nlast";
  MemorySource source(text, "mem.txt");
  LineReader reader(source);
  std::string_view line;
  std::vector<std::string> lines;
  while (reader.next_line(&line)) lines.emplace_back(line);
  EXPECT_EQ(lines, (std::vector<std::string>{"first", "second", "", "last"}));
  EXPECT_EQ(reader.line_number(), 4u);

  const std::string mixed = std::string("HEADER\n") + std::string("\0\1\2\3\n\n", 6);
  MemorySource raw(mixed, "mixed.bin");
  LineReader header(raw);
  ASSERT_TRUE(header.next_line(&line));
  EXPECT_EQ(line, "HEADER");
  ASSERT_EQ(header.remaining(), std::optional<std::uint64_t>(6));
  char bytes[8];
  ASSERT_EQ(header.read(bytes, sizeof(bytes)), 6u);
  EXPECT_EQ(std::string(bytes, 4), std::string("\0\1\2\3", 4));
}

TEST(LineReaderTest, RefusesLongLinesAndNulBytesAtOnce) {
  const std::string endless(1 << 20, 'a');
  MemorySource long_source(endless, "long.txt");
  LineReader long_reader(long_source, 1000);
  std::string_view line;
  EXPECT_EQ(error_of([&] { long_reader.next_line(&line); }),
            "long.txt:1: line is longer than 1000 bytes (not a text file of this format?)");

  const std::string zeros(1 << 20, '\0');
  MemorySource zero_source(zeros, "zeros");
  LineReader zero_reader(zero_source);
  EXPECT_EQ(error_of([&] { zero_reader.next_line(&line); }),
            "zeros:1: holds a NUL byte (a binary file?)");

  const std::string second = std::string("ok\nbad\0line\n", 12);
  MemorySource second_source(second, "s.txt");
  LineReader second_reader(second_source);
  ASSERT_TRUE(second_reader.next_line(&line));
  EXPECT_EQ(error_of([&] { second_reader.next_line(&line); }),
            "s.txt:2: holds a NUL byte (a binary file?)");
}

TEST(LineReaderTest, LinesAcrossManyBufferRefills) {
  std::string text;
  for (int k = 0; k < 200000; ++k) text += std::to_string(k) + (k % 3 == 0 ? "\r\n" : "\n");
  MemorySource source(text, "many.txt");
  LineReader reader(source, 64);
  std::string_view line;
  int k = 0;
  while (reader.next_line(&line)) {
    ASSERT_EQ(line, std::to_string(k)) << k;
    ++k;
  }
  EXPECT_EQ(k, 200000);
}

TEST(InputFileTest, KindsOfPathAreCheckedBeforeReading) {
  const fs::path dir = test::scratch_dir("input_kinds");
  EXPECT_EQ(error_of([&] { InputFile((dir / "missing").string(), InputKind::kStreamable); }),
            (dir / "missing").string() + ": no such file");
  EXPECT_EQ(error_of([&] { InputFile(dir, InputKind::kStreamable); }),
            dir.string() + ": is a directory, not a file");
  EXPECT_EQ(error_of([] { InputFile("/dev/zero", InputKind::kRegular); }),
            "/dev/zero: is a character device, not a regular file (this input is read from "
            "regular files only)");
  const fs::path fifo = dir / "fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_EQ(error_of([&] { InputFile(fifo, InputKind::kRegular); }),
            fifo.string() +
                ": is a FIFO, not a regular file (this input is read from regular "
                "files only)");
  // A FIFO is read as a stream (e.g. `<(command)`), with no size.
  std::thread writer([&] { write_text(fifo, "line one\nline two\n"); });
  InputFile stream(fifo, InputKind::kStreamable);
  EXPECT_FALSE(stream.size().has_value());
  LineReader reader(stream);
  std::string_view line;
  ASSERT_TRUE(reader.next_line(&line));
  EXPECT_EQ(line, "line one");
  ASSERT_TRUE(reader.next_line(&line));
  EXPECT_EQ(line, "line two");
  EXPECT_FALSE(reader.next_line(&line));
  writer.join();
  // /dev/zero as text stops at its first line, whatever its length.
  InputFile zero("/dev/zero", InputKind::kStreamable);
  LineReader zero_reader(zero);
  EXPECT_EQ(error_of([&] { zero_reader.next_line(&line); }),
            "/dev/zero:1: holds a NUL byte (a binary file?)");
}

TEST(AtomicFileTest, ReplacesRegularFilesKeepingTheirMode) {
  const fs::path dir = test::scratch_dir("atomic_mode");
  const fs::path path = dir / "out.txt";
  write_text(path, "old");
  ASSERT_EQ(::chmod(path.c_str(), 0640), 0);
  write_file_atomically(path, [](std::ostream& out) { out << "new"; });
  EXPECT_EQ(read_text(path), "new");
  struct stat s {};
  ASSERT_EQ(::stat(path.c_str(), &s), 0);
  EXPECT_EQ(s.st_mode & 07777, 0640u);
  EXPECT_EQ(names_in(dir), (std::vector<std::string>{"out.txt"}));
}

TEST(AtomicFileTest, AFailedWriteLeavesTheOldFileAndNoTemporary) {
  const fs::path dir = test::scratch_dir("atomic_fail");
  const fs::path path = dir / "out.txt";
  write_text(path, "old");
  EXPECT_EQ(error_of([&] {
              write_file_atomically(path, [](std::ostream& out) {
                out << "partial";
                throw Error("the writer failed");
              });
            }),
            "the writer failed");
  EXPECT_EQ(read_text(path), "old");
  EXPECT_EQ(names_in(dir), (std::vector<std::string>{"out.txt"}));
  // A full device: the error names the path and the reason.
  EXPECT_EQ(error_of([] {
              write_file_atomically("/dev/full",
                                    [](std::ostream& out) { out << std::string(1 << 16, 'x'); });
            }),
            "/dev/full: write failed: No space left on device");
}

TEST(AtomicFileTest, FollowsSymbolicLinksAndKeepsThem) {
  const fs::path dir = test::scratch_dir("atomic_link");
  write_text(dir / "target.txt", "old");
  fs::create_symlink("target.txt", dir / "link.txt");
  write_file_atomically(dir / "link.txt", [](std::ostream& out) { out << "new"; });
  EXPECT_TRUE(fs::is_symlink(dir / "link.txt"));
  EXPECT_EQ(read_text(dir / "target.txt"), "new");
  // A dangling link: the file it names is created.
  fs::create_symlink("sub/created.txt", dir / "dangling.txt");
  fs::create_directory(dir / "sub");
  write_file_atomically(dir / "dangling.txt", [](std::ostream& out) { out << "made"; });
  EXPECT_TRUE(fs::is_symlink(dir / "dangling.txt"));
  EXPECT_EQ(read_text(dir / "sub" / "created.txt"), "made");
  // A loop of links is an error, not a hang.
  fs::create_symlink("loop_b", dir / "loop_a");
  fs::create_symlink("loop_a", dir / "loop_b");
  EXPECT_EQ(error_of([&] {
              write_file_atomically(dir / "loop_a", [](std::ostream& out) { out << "x"; });
            }),
            (dir / "loop_a").string() + ": too many levels of symbolic links");
}

TEST(AtomicFileTest, DevicesAndFifosAreWrittenThroughNeverReplaced) {
  write_file_atomically("/dev/null", [](std::ostream& out) { out << "discarded"; });
  struct stat s {};
  ASSERT_EQ(::stat("/dev/null", &s), 0);
  EXPECT_TRUE(S_ISCHR(s.st_mode));

  const fs::path dir = test::scratch_dir("atomic_fifo");
  const fs::path fifo = dir / "pipe";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string received;
  std::thread reader([&] { received = read_text(fifo); });
  write_file_atomically(fifo, [](std::ostream& out) { out << "through the pipe"; });
  reader.join();
  EXPECT_EQ(received, "through the pipe");
  ASSERT_EQ(::lstat(fifo.c_str(), &s), 0);
  EXPECT_TRUE(S_ISFIFO(s.st_mode));
  EXPECT_EQ(names_in(dir), (std::vector<std::string>{"pipe"}));

  EXPECT_EQ(error_of([&] { write_file_atomically(dir, [](std::ostream&) {}); }),
            dir.string() + ": is a directory, not a file");
}

TEST(AtomicFileTest, LongNamesGetTemporaryNamesThatFit) {
  const fs::path dir = test::scratch_dir("atomic_long");
  const std::string name(250, 'n');
  write_file_atomically(dir / name, [](std::ostream& out) { out << "fits"; });
  EXPECT_EQ(read_text(dir / name), "fits");
  EXPECT_EQ(names_in(dir), (std::vector<std::string>{name}));
}

TEST(AtomicFileTest, SameFileSeesThroughLinks) {
  const fs::path dir = test::scratch_dir("same_file");
  write_text(dir / "a.txt", "a");
  fs::create_symlink("a.txt", dir / "link.txt");
  fs::create_hard_link(dir / "a.txt", dir / "hard.txt");
  EXPECT_TRUE(same_file(dir / "a.txt", dir / "link.txt"));
  EXPECT_TRUE(same_file(dir / "hard.txt", dir / "link.txt"));
  EXPECT_FALSE(same_file(dir / "a.txt", dir / "missing.txt"));
}

TEST(OutputFolderTest, CompleteOnCommitAbsentOtherwise) {
  const fs::path dir = test::scratch_dir("folder_commit");
  {
    OutputFolder folder(dir / "parent" / "out", "test");
    write_text(folder.path() / "a.txt", "a");
    EXPECT_FALSE(fs::exists(dir / "parent" / "out"));
    // Not committed: nothing stays, not even the parent folder it created.
  }
  EXPECT_EQ(names_in(dir), std::vector<std::string>{});
  {
    OutputFolder folder(dir / "out", "carat test");
    write_text(folder.path() / "a.txt", "a");
    folder.commit();
  }
  EXPECT_EQ(names_in(dir), (std::vector<std::string>{"out"}));
  EXPECT_EQ(names_in(dir / "out"), (std::vector<std::string>{".carat-output", "a.txt"}));
  EXPECT_EQ(read_text(dir / "out" / ".carat-output"), "written by carat test\n");
  // An earlier carat output is replaced whole: no stale file survives.
  {
    OutputFolder folder(dir / "out", "carat test");
    write_text(folder.path() / "b.txt", "b");
    folder.commit();
  }
  EXPECT_EQ(names_in(dir / "out"), (std::vector<std::string>{".carat-output", "b.txt"}));
  EXPECT_EQ(names_in(dir), (std::vector<std::string>{"out"}));
}

TEST(OutputFolderTest, RefusesWhatCaratDidNotWrite) {
  const fs::path dir = test::scratch_dir("folder_refuse");
  fs::create_directory(dir / "mine");
  write_text(dir / "mine" / "thesis.tex", "precious");
  EXPECT_EQ(error_of([&] { OutputFolder(dir / "mine", "carat test"); }),
            (dir / "mine").string() +
                ": exists, is not empty and was not written by carat (it has no .carat-output "
                "file); choose another output folder or remove this one");
  EXPECT_EQ(read_text(dir / "mine" / "thesis.tex"), "precious");
  write_text(dir / "file", "x");
  EXPECT_EQ(
      error_of([&] { OutputFolder(dir / "file", "carat test"); }),
      (dir / "file").string() + ": exists and is not a folder (an output folder is needed here)");
  EXPECT_EQ(error_of([] { OutputFolder("/dev/null", "carat test"); }),
            "/dev/null: exists and is not a folder (an output folder is needed here)");
  // An empty folder is filled; a link to a folder is followed and stays a link.
  fs::create_directory(dir / "empty");
  fs::create_symlink("empty", dir / "link");
  {
    OutputFolder folder(dir / "link", "carat test");
    write_text(folder.path() / "a.txt", "a");
    folder.commit();
  }
  EXPECT_TRUE(fs::is_symlink(dir / "link"));
  EXPECT_EQ(read_text(dir / "empty" / "a.txt"), "a");
}

TEST(TemporaryPathsTest, AnInterruptedWriterLeavesNothing) {
  const fs::path dir = test::scratch_dir("temporaries_exit");
  write_text(dir / "out.txt", "old");
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    // A writer that never finishes, one folder output in progress, then the exit cleanup.
    std::thread([&] {
      write_file_atomically(dir / "out.txt", [](std::ostream& out) {
        out << "partial" << std::flush;
        for (;;) std::this_thread::sleep_for(std::chrono::seconds(1));
      });
    }).detach();
    OutputFolder folder(dir / "folder", "carat test");
    write_text(folder.path() / "a.txt", "a");
    for (int k = 0; k < 500 && names_in(dir).size() < 3; ++k) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    const bool started = names_in(dir).size() == 3;  // out.txt + two temporaries
    remove_temporaries_for_exit();
    _exit(started ? 0 : 3);
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << "the temporaries never appeared";
  EXPECT_EQ(names_in(dir), (std::vector<std::string>{"out.txt"}));
  EXPECT_EQ(read_text(dir / "out.txt"), "old");
}

}  // namespace
}  // namespace carat
