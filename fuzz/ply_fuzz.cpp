// Fuzzes the PLY reader through a scratch file: any input must read or throw carat::Error.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "carat/registration/point_cloud_io.hpp"
#include "carat/solver/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::filesystem::path path = std::filesystem::temp_directory_path() /
                                            ("carat_ply_fuzz_" + std::to_string(getpid()) + ".ply");
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  }
  try {
    carat::ReadOptions options;
    options.drop_non_finite = size % 2 == 0;
    (void)carat::read_ply(path, options);
  } catch (const carat::Error&) {
  }
  return 0;
}
