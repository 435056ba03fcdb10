#pragma once

/// A folder of output files that ends either complete or untouched: everything is written into a
/// fresh temporary folder beside the target (registered in temporary_paths.hpp), which commit()
/// moves into place. The target may not exist yet, be an empty folder, or be a folder an earlier
/// carat run wrote (it holds the marker file `.carat-output`); that one is replaced as a whole
/// (atomically where the file system can exchange two names). Any other existing path — a
/// non-empty folder carat did not write, a file, a device — is refused before anything is
/// written, so that no user data is ever deleted.

#include <filesystem>
#include <string>
#include <vector>

namespace carat {

/// A temporary folder that becomes the output folder on commit().
class OutputFolder {
 public:
  /// Name of the marker file that commit() writes into the folder (its content names the writer).
  static constexpr const char* kMarker = ".carat-output";

  /// Checks `target` (links followed) and creates the temporary folder beside it, creating
  /// missing parent folders. `writer` (e.g. "carat demo") goes into the marker. Throws
  /// carat::Error naming the target if it cannot be used.
  OutputFolder(const std::filesystem::path& target, std::string writer);
  /// Removes the temporary folder (and the parent folders it created) unless committed.
  ~OutputFolder();
  OutputFolder(const OutputFolder&) = delete;
  OutputFolder& operator=(const OutputFolder&) = delete;

  /// The temporary folder: write the output files here.
  const std::filesystem::path& path() const { return temporary_; }
  /// Where commit() puts the folder (links followed).
  const std::filesystem::path& target() const { return target_; }
  /// Writes the marker and moves the folder into place, replacing an earlier carat output
  /// there. Throws carat::Error naming the target if that is no longer possible.
  void commit();

  /// Throws carat::Error naming `target` unless it can receive an output folder: it is missing,
  /// an empty folder, or a folder with the marker.
  static void check_target(const std::filesystem::path& target);

 private:
  std::filesystem::path requested_;
  std::filesystem::path target_;
  std::filesystem::path temporary_;
  std::string writer_;
  std::vector<std::filesystem::path> created_parents_;  // deepest last
  bool committed_ = false;
};

}  // namespace carat
