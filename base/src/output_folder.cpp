#include "carat/base/output_folder.hpp"

#include <fcntl.h>
#include <stdio.h>
#include <sys/stat.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <system_error>

#include "carat/base/atomic_file.hpp"
#include "carat/base/error.hpp"
#include "carat/base/temporary_paths.hpp"
#include "temporary_name.hpp"

namespace carat {
namespace fs = std::filesystem;
namespace {

enum class TargetState { kMissing, kEmpty, kCaratOutput };

/// What is at `target` (links followed), or an error naming `name` when it cannot take a folder.
TargetState inspect(const fs::path& target, const std::string& name) {
  struct stat s {};
  if (::stat(target.c_str(), &s) != 0) {
    if (errno == ENOENT) return TargetState::kMissing;
    throw Error(name + ": cannot use as an output folder: " + std::strerror(errno));
  }
  if (!S_ISDIR(s.st_mode)) {
    throw Error(name + ": exists and is not a folder (an output folder is needed here)");
  }
  std::error_code ec;
  if (fs::is_regular_file(target / OutputFolder::kMarker, ec)) return TargetState::kCaratOutput;
  fs::directory_iterator it(target, ec);
  if (ec) throw Error(name + ": cannot list the folder: " + ec.message());
  if (it == fs::directory_iterator()) return TargetState::kEmpty;
  throw Error(name + ": exists, is not empty and was not written by carat (it has no " +
              std::string(OutputFolder::kMarker) +
              " file); choose another output folder or remove this one");
}

/// `path` made absolute with its links followed and "." / ".." resolved.
fs::path absolute_target(const fs::path& path) {
  std::error_code ec;
  fs::path absolute = fs::absolute(path, ec);
  if (ec) throw Error(path.string() + ": cannot resolve the path: " + ec.message());
  absolute = resolve_output_path(absolute.lexically_normal());
  fs::path normal = fs::weakly_canonical(absolute, ec);
  if (ec) throw Error(path.string() + ": cannot resolve the path: " + ec.message());
  if (normal.filename().empty()) normal = normal.parent_path();  // "dir/" -> "dir"
  return normal;
}

}  // namespace

void OutputFolder::check_target(const fs::path& target) {
  const fs::path absolute = absolute_target(target);
  std::error_code ec;
  if (absolute == absolute.root_path() || same_file(absolute, fs::current_path(ec))) {
    throw Error(target.string() +
                ": is the root or the current folder; choose a folder of its own for the output");
  }
  (void)inspect(absolute, target.string());
}

OutputFolder::OutputFolder(const fs::path& target, std::string writer)
    : requested_(target), writer_(std::move(writer)) {
  check_target(target);
  target_ = absolute_target(target);
  const std::string name = requested_.string();
  // Missing parents are created (and removed again if nothing is committed).
  std::vector<fs::path> missing;
  for (fs::path p = target_.parent_path(); !p.empty() && p != p.root_path(); p = p.parent_path()) {
    std::error_code ec;
    if (fs::exists(p, ec)) break;
    missing.push_back(p);
  }
  for (auto it = missing.rbegin(); it != missing.rend(); ++it) {
    std::error_code ec;
    if (!fs::create_directory(*it, ec) && ec) {
      for (auto back = created_parents_.rbegin(); back != created_parents_.rend(); ++back) {
        std::error_code ignored;
        fs::remove(*back, ignored);
      }
      throw Error(name + ": cannot create the folder " + it->string() + ": " + ec.message());
    }
    created_parents_.push_back(*it);
  }
  try {
    temporary_ = create_temporary([&] {
      for (int attempt = 0;; ++attempt) {
        const fs::path candidate = target_.parent_path() / internal::temporary_name(target_, "tmp");
        if (::mkdir(candidate.c_str(), 0777) == 0) return candidate;
        if (errno != EEXIST || attempt >= 100) {
          throw Error(name + ": cannot create a folder in " + target_.parent_path().string() +
                      ": " + std::strerror(errno));
        }
      }
    });
  } catch (...) {
    for (auto back = created_parents_.rbegin(); back != created_parents_.rend(); ++back) {
      std::error_code ignored;
      fs::remove(*back, ignored);
    }
    throw;
  }
}

OutputFolder::~OutputFolder() {
  if (committed_) return;
  release_temporary(temporary_, [&] {
    std::error_code ignored;
    fs::remove_all(temporary_, ignored);
  });
  for (auto back = created_parents_.rbegin(); back != created_parents_.rend(); ++back) {
    std::error_code ignored;
    fs::remove(*back, ignored);  // only if still empty
  }
}

void OutputFolder::commit() {
  if (committed_) throw Error(requested_.string() + ": the output folder was committed already");
  const std::string name = requested_.string();
  {
    std::ofstream marker(temporary_ / kMarker, std::ios::binary | std::ios::trunc);
    marker << "written by " << writer_ << '\n';
    marker.close();
    if (!marker) throw Error(name + ": cannot write " + (temporary_ / kMarker).string());
  }
  release_temporary(temporary_, [&] {
    const TargetState state = inspect(target_, name);
    if (state == TargetState::kCaratOutput) {
      // Swap the two names atomically, then remove the earlier output (now at temporary_).
      if (::renameat2(AT_FDCWD, temporary_.c_str(), AT_FDCWD, target_.c_str(), RENAME_EXCHANGE) !=
          0) {
        if (errno != EINVAL && errno != ENOSYS) {
          throw Error(name + ": cannot move the output folder into place: " + std::strerror(errno));
        }
        // No exchange on this file system: move the old folder aside first.
        const fs::path aside = target_.parent_path() / internal::temporary_name(target_, "old");
        std::error_code ec;
        fs::rename(target_, aside, ec);
        if (ec) throw Error(name + ": cannot replace the earlier output: " + ec.message());
        fs::rename(temporary_, target_, ec);
        if (ec) {
          std::error_code ignored;
          fs::rename(aside, target_, ignored);
          throw Error(name + ": cannot move the output folder into place: " + ec.message());
        }
        fs::remove_all(aside, ec);
      } else {
        std::error_code ignored;
        fs::remove_all(temporary_, ignored);
      }
    } else {
      std::error_code ec;
      fs::rename(temporary_, target_, ec);  // a missing target, or an empty folder (replaced)
      if (ec) throw Error(name + ": cannot move the output folder into place: " + ec.message());
    }
  });
  committed_ = true;
}

}  // namespace carat
