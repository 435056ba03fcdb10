#include "carat/base/temporary_paths.hpp"

#include <algorithm>
#include <mutex>
#include <vector>

namespace carat {
namespace {

struct Registry {
  std::mutex mutex;
  std::vector<std::filesystem::path> paths;
};

Registry& registry() {
  static Registry* const instance = new Registry;  // never destroyed: usable until exit
  return *instance;
}

}  // namespace

std::filesystem::path create_temporary(const std::function<std::filesystem::path()>& create) {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  std::filesystem::path path = create();
  r.paths.push_back(path);
  return path;
}

void release_temporary(const std::filesystem::path& path, const std::function<void()>& finish) {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  const auto forget = [&] {
    const auto it = std::find(r.paths.begin(), r.paths.end(), path);
    if (it != r.paths.end()) r.paths.erase(it);
  };
  try {
    if (finish) finish();
  } catch (...) {
    forget();
    throw;
  }
  forget();
}

void remove_temporaries_for_exit() noexcept {
  Registry& r = registry();
  r.mutex.lock();  // never unlocked: the process ends next
  for (const auto& path : r.paths) {
    // Another thread may still be writing files into a temporary folder. Renamed first, the
    // folder gets no new entries (writers address it by its old path), so the removal that
    // follows cannot be outrun by a file created while it runs.
    std::error_code ignored;
    std::filesystem::path doomed = path;
    doomed += ".removing";
    std::filesystem::rename(path, doomed, ignored);
    if (ignored) doomed = path;
    for (int attempt = 0; attempt < 3; ++attempt) {
      std::filesystem::remove_all(doomed, ignored);
      if (!ignored) break;
    }
  }
  r.paths.clear();
}

}  // namespace carat
