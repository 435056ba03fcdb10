#include "carat/registration/io/scan_folder.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <map>
#include <numeric>
#include <system_error>

#include "carat/base/error.hpp"
#include "carat/registration/io/point_cloud_io.hpp"

namespace carat {
namespace fs = std::filesystem;

const char* to_string(BinLayout layout) {
  switch (layout) {
    case BinLayout::kAuto:
      return "auto";
    case BinLayout::kXyz:
      return "xyz";
    case BinLayout::kXyzi:
      return "xyzi";
  }
  return "unknown";
}

BinLayout parse_bin_layout(std::string_view name) {
  if (name == "auto") return BinLayout::kAuto;
  if (name == "xyz") return BinLayout::kXyz;
  if (name == "xyzi") return BinLayout::kXyzi;
  throw Error("unknown .bin layout " + quote_bytes(name) + " (valid: auto, xyz, xyzi)");
}

bool natural_less(std::string_view a, std::string_view b) {
  std::size_t i = 0, j = 0;
  const auto digit = [](char c) { return c >= '0' && c <= '9'; };
  while (i < a.size() && j < b.size()) {
    if (digit(a[i]) && digit(b[j])) {
      std::size_t ie = i, je = j;
      while (ie < a.size() && digit(a[ie])) ++ie;
      while (je < b.size() && digit(b[je])) ++je;
      // Compare as numbers: skip leading zeros, then by length, then digit by digit.
      std::size_t is = i, js = j;
      while (is + 1 < ie && a[is] == '0') ++is;
      while (js + 1 < je && b[js] == '0') ++js;
      if (ie - is != je - js) return ie - is < je - js;
      const int c = a.substr(is, ie - is).compare(b.substr(js, je - js));
      if (c != 0) return c < 0;
      if (ie - i != je - j) return ie - i < je - j;  // fewer leading zeros first
      i = ie;
      j = je;
    } else {
      if (a[i] != b[j]) return a[i] < b[j];
      ++i;
      ++j;
    }
  }
  return a.size() - i < b.size() - j;
}

bool is_frame_file_name(std::string_view name) {
  const auto dot = name.rfind('.');
  if (dot == std::string_view::npos || dot == 0) return false;
  const std::string_view ext = name.substr(dot);
  return ext == ".bin" || ext == ".pcd" || ext == ".ply";
}

bool looks_like_frame_name(std::string_view name) {
  std::string folded;
  for (const char c : name)
    folded += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  // Trailing blanks and editor backups ("x.bin ", "x.bin~") hide the extension.
  while (!folded.empty() &&
         (std::isspace(static_cast<unsigned char>(folded.back())) != 0 || folded.back() == '~')) {
    folded.pop_back();
  }
  if (is_frame_file_name(folded)) return true;
  // A frame extension before another one: compressed, renamed or partial ("x.bin.gz").
  const auto last = folded.rfind('.');
  return last != std::string::npos && last > 0 && is_frame_file_name(folded.substr(0, last));
}

std::vector<ScanFile> list_scan_folder(const fs::path& dir, BinLayout layout) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw Error(dir.string() + ": not a folder of frames");
  std::vector<ScanFile> flat, nested;
  std::vector<fs::path> folders_without_points;
  fs::directory_iterator it(dir, ec);
  if (ec) throw Error(dir.string() + ": cannot list the folder: " + ec.message());
  const std::string hide =
      "; move it out of the folder or hide it (a name starting with '.') to run without it";
  for (const auto& entry : it) {
    const fs::path& p = entry.path();
    const std::string file = p.filename().string();
    if (file.empty() || file[0] == '.') continue;  // hidden, as ls does (also macOS ._ files)
    std::error_code status_ec;
    const bool is_dir = entry.is_directory(status_ec);
    if (is_dir && fs::exists(p / "points.bin", status_ec)) {
      if (!fs::is_regular_file(p / "points.bin", status_ec)) {
        throw Error((p / "points.bin").string() +
                    ": is not a regular file (frames are read from regular files)");
      }
      nested.push_back({p / "points.bin", file, KittiFormat::kXyz});
      continue;
    }
    if (is_dir) {
      // Skipping an entry named like a frame would pair every later frame with the wrong pose.
      if (looks_like_frame_name(file)) {
        throw Error(p.string() + ": is a directory named like a frame file" + hide);
      }
      folders_without_points.push_back(p);
      continue;
    }
    if (!is_frame_file_name(file)) {
      if (looks_like_frame_name(file)) {
        throw Error(p.string() +
                    ": is named like a frame, but frames are read only from *.bin, *.pcd and "
                    "*.ply (lower case)" +
                    hide);
      }
      continue;
    }
    if (!entry.is_regular_file(status_ec)) {
      throw Error(p.string() + ": is not a regular file (frames are read from regular files)");
    }
    flat.push_back({p, p.stem().string(), KittiFormat::kXyzi});
  }
  if (!nested.empty() && !folders_without_points.empty()) {
    std::sort(folders_without_points.begin(), folders_without_points.end());
    throw Error(folders_without_points.front().string() +
                ": a folder without points.bin among <frame>/points.bin frames" + hide);
  }
  if (!flat.empty() && !nested.empty()) {
    throw Error(dir.string() +
                ": holds both scan files and <frame>/points.bin folders; keep one layout");
  }
  std::vector<ScanFile> scans = flat.empty() ? std::move(nested) : std::move(flat);
  if (scans.empty()) {
    throw Error(dir.string() + ": no frames (expected *.bin, *.pcd, *.ply or <frame>/points.bin)");
  }
  std::sort(scans.begin(), scans.end(), [](const ScanFile& a, const ScanFile& b) {
    if (a.name != b.name) return natural_less(a.name, b.name);
    return a.path < b.path;
  });
  if (layout != BinLayout::kAuto) {
    for (ScanFile& scan : scans) {
      scan.bin_format = layout == BinLayout::kXyz ? KittiFormat::kXyz : KittiFormat::kXyzi;
    }
  }
  return scans;
}

PointCloud read_scan(const ScanFile& scan, const ReadOptions& options) {
  return read_point_cloud(scan.path, scan.bin_format, options);
}

namespace {

/// The scans' names as numbers when every name is a decimal number below 2^64 and no two are
/// equal; else empty.
std::vector<std::uint64_t> distinct_name_numbers(const std::vector<ScanFile>& scans) {
  std::vector<std::uint64_t> numbers;
  for (const ScanFile& scan : scans) {
    std::uint64_t number = 0;
    const std::string& name = scan.name;
    const auto [ptr, ec] = std::from_chars(name.data(), name.data() + name.size(), number);
    if (name.empty() || name[0] < '0' || name[0] > '9' || ec != std::errc() ||
        ptr != name.data() + name.size()) {
      return {};
    }
    numbers.push_back(number);
  }
  std::vector<std::uint64_t> sorted = numbers;
  std::sort(sorted.begin(), sorted.end());
  if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) return {};
  return numbers;
}

}  // namespace

std::vector<std::uint64_t> scan_graph_ids(const std::vector<ScanFile>& scans) {
  std::vector<std::uint64_t> ids = distinct_name_numbers(scans);
  if (ids.empty()) {
    ids.resize(scans.size());
    std::iota(ids.begin(), ids.end(), std::uint64_t{0});
  }
  return ids;
}

Trajectory poses_in_scan_order(const Trajectory& trajectory, TrajectoryFormat format,
                               const std::vector<ScanFile>& scans, const std::string& poses_name) {
  if (trajectory.poses.size() != scans.size()) {
    const fs::path folder = scans.empty() ? fs::path() : scans.front().path.parent_path();
    throw Error(poses_name + " has " + std::to_string(trajectory.poses.size()) +
                " poses but there are " + std::to_string(scans.size()) + " frames" +
                (folder.empty() ? std::string() : " in " + folder.string()));
  }
  if (format != TrajectoryFormat::kGraph) return trajectory;
  std::map<std::uint64_t, std::size_t> by_id;
  for (std::size_t k = 0; k < trajectory.poses.size(); ++k) {
    by_id.emplace(trajectory.ids.empty() ? static_cast<std::uint64_t>(trajectory.stamps[k])
                                         : trajectory.ids[k],
                  k);
  }
  // Numbered scans take the vertex of their number; others the ids in increasing order (which
  // are 0, 1, ... in a file carat wrote for them).
  const std::vector<std::uint64_t> numbers = distinct_name_numbers(scans);
  Trajectory ordered;
  auto next = by_id.begin();
  for (std::size_t f = 0; f < scans.size(); ++f, ++next) {
    const auto pose = numbers.empty() ? next : by_id.find(numbers[f]);
    if (pose == by_id.end()) {
      throw Error(poses_name + ": has no vertex v" + std::to_string(numbers[f]) + " for frame " +
                  scans[f].path.string() + " (graph poses pair with frames by id)");
    }
    ordered.stamps.push_back(trajectory.stamps[pose->second]);
    ordered.poses.push_back(trajectory.poses[pose->second]);
    ordered.ids.push_back(pose->first);
  }
  return ordered;
}

}  // namespace carat
