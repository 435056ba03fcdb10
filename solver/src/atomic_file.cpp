#include "carat/solver/atomic_file.hpp"

#include <fstream>
#include <random>
#include <string>
#include <system_error>

#include "carat/solver/error.hpp"

namespace carat {

void write_file_atomically(const std::filesystem::path& path,
                           const std::function<void(std::ostream&)>& write) {
  namespace fs = std::filesystem;
  std::random_device device;
  const fs::path temporary =
      path.parent_path() / (path.filename().string() + ".tmp-" + std::to_string(device()));
  const auto discard = [&] {
    std::error_code ignored;
    fs::remove(temporary, ignored);
  };
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    if (!out) throw Error(path.string() + ": cannot open for writing");
    try {
      write(out);
    } catch (...) {
      out.close();
      discard();
      throw;
    }
    out.flush();
    if (!out) {
      out.close();
      discard();
      throw Error(path.string() + ": write failed");
    }
  }
  std::error_code ec;
  fs::rename(temporary, path, ec);
  if (ec) {
    discard();
    throw Error(path.string() + ": cannot move the finished file into place: " + ec.message());
  }
}

}  // namespace carat
