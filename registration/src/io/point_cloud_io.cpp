#include "carat/registration/io/point_cloud_io.hpp"

#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <new>
#include <string>
#include <vector>

#include "carat/base/atomic_file.hpp"
#include "carat/base/error.hpp"
#include "carat/base/input_file.hpp"

namespace carat {
namespace {

/// A scalar field of a record: its byte offset, size, kind and count.
struct Field {
  std::string name;
  std::size_t offset = 0;
  std::size_t size = 0;
  char kind = 'F';  // 'F' float, 'I' signed, 'U' unsigned
  std::size_t count = 1;
};

/// Largest record (one point's bytes) a header may declare.
constexpr std::size_t kMaxRecordBytes = std::size_t{1} << 20;
/// Bytes read at a time from binary data.
constexpr std::size_t kChunkBytes = std::size_t{1} << 20;

[[noreturn]] void fail(const std::string& name, const std::string& problem) {
  throw Error(name + ": " + problem);
}

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

std::vector<std::string_view> words(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_space(line[i])) ++i;
    const std::size_t start = i;
    while (i < line.size() && !is_space(line[i])) ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
  return out;
}

/// A non-negative integer of the header, checked for form and range.
std::uint64_t parse_count(std::string_view text, const std::string& name, const std::string& what) {
  std::uint64_t value = 0;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec == std::errc::result_out_of_range) {
    fail(name, what + " " + quote_bytes(text) + " is out of range");
  }
  if (ec != std::errc() || ptr != text.data() + text.size()) {
    fail(name, "cannot read " + what + " from " + quote_bytes(text));
  }
  return value;
}

std::uint64_t checked_multiply(std::uint64_t a, std::uint64_t b, const std::string& name,
                               const std::string& what) {
  std::uint64_t product = 0;
  if (__builtin_mul_overflow(a, b, &product)) fail(name, what + " overflows");
  return product;
}

std::uint64_t checked_add(std::uint64_t a, std::uint64_t b, const std::string& name,
                          const std::string& what) {
  std::uint64_t sum = 0;
  if (__builtin_add_overflow(a, b, &sum)) fail(name, what + " overflows");
  return sum;
}

void check_point_count(std::uint64_t points, const std::string& name, const ReadOptions& options) {
  if (points > options.max_points) {
    fail(name, "announces " + std::to_string(points) + " points, more than the " +
                   std::to_string(options.max_points) + " carat reads from one file");
  }
}

/// Whether x, y, z can be read from a field of this kind and size.
bool readable(char kind, std::size_t size) {
  if (kind == 'F') return size == 4 || size == 8;
  return size == 1 || size == 2 || size == 4 || size == 8;
}

double read_binary(const char* p, const Field& f) {
  switch (f.kind) {
    case 'F':
      if (f.size == 4) {
        float v;
        std::memcpy(&v, p, 4);
        return v;
      } else {
        double v;
        std::memcpy(&v, p, 8);
        return v;
      }
    case 'I':
      switch (f.size) {
        case 1:
          return static_cast<std::int8_t>(*p);
        case 2: {
          std::int16_t v;
          std::memcpy(&v, p, 2);
          return v;
        }
        case 4: {
          std::int32_t v;
          std::memcpy(&v, p, 4);
          return v;
        }
        default: {
          std::int64_t v;
          std::memcpy(&v, p, 8);
          return static_cast<double>(v);
        }
      }
    default:
      switch (f.size) {
        case 1:
          return static_cast<std::uint8_t>(*p);
        case 2: {
          std::uint16_t v;
          std::memcpy(&v, p, 2);
          return v;
        }
        case 4: {
          std::uint32_t v;
          std::memcpy(&v, p, 4);
          return v;
        }
        default: {
          std::uint64_t v;
          std::memcpy(&v, p, 8);
          return static_cast<double>(v);
        }
      }
  }
}

void add_point(PointCloud& cloud, const double xyz[3], std::uint64_t index, const std::string& name,
               const ReadOptions& options) {
  if (!std::isfinite(xyz[0]) || !std::isfinite(xyz[1]) || !std::isfinite(xyz[2])) {
    if (options.drop_non_finite) return;
    fail(name, "point " + std::to_string(index) + " is not finite");
  }
  const float x = static_cast<float>(xyz[0]), y = static_cast<float>(xyz[1]),
              z = static_cast<float>(xyz[2]);
  if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) {
    if (options.drop_non_finite) return;
    fail(name, "point " + std::to_string(index) + " is too large for float32");
  }
  cloud.points.emplace_back(x, y, z);
}

double parse_value(std::string_view text, const std::string& name, std::uint64_t point) {
  double value = 0.0;
  std::string_view digits = text;
  if (digits.size() > 1 && digits[0] == '+' && digits[1] != '-' && digits[1] != '+') {
    digits.remove_prefix(1);
  }
  const auto [ptr, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
  if (ec == std::errc() && ptr == digits.data() + digits.size()) return value;  // also nan, inf
  if (ec == std::errc::result_out_of_range && ptr == digits.data() + digits.size()) {
    fail(name, "point " + std::to_string(point) + ": " + quote_bytes(text) + " is out of range");
  }
  fail(name, "point " + std::to_string(point) + ": cannot read a number from " + quote_bytes(text));
}

/// Positions of the x, y, z fields, checked to be single, readable and present once.
std::array<std::size_t, 3> xyz_fields(const std::vector<Field>& fields, const std::string& name) {
  std::array<std::size_t, 3> out{};
  const char* names[3] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a) {
    bool found = false;
    for (std::size_t i = 0; i < fields.size(); ++i) {
      if (fields[i].name != names[a]) continue;
      if (found) fail(name, std::string("field '") + names[a] + "' is declared twice");
      found = true;
      out[static_cast<std::size_t>(a)] = i;
    }
    if (!found) fail(name, std::string("no '") + names[a] + "' field");
    const Field& f = fields[out[static_cast<std::size_t>(a)]];
    if (f.count != 1) fail(name, std::string("field '") + names[a] + "' must have COUNT 1");
    if (!readable(f.kind, f.size)) {
      fail(name, std::string("field '") + names[a] + "' has an unsupported type " + f.kind +
                     std::to_string(f.size));
    }
  }
  return out;
}

/// Reads `points` ascii records (one point per line, values in field order).
/// Whether `value` fits a field of integer kind: whole, and in the range of its size.
bool fits_integer(double value, const Field& f) {
  if (value != std::floor(value)) return false;
  const double bits = 8.0 * static_cast<double>(f.size);
  if (f.kind == 'U') return value >= 0.0 && value < std::ldexp(1.0, static_cast<int>(bits));
  return value >= -std::ldexp(1.0, static_cast<int>(bits) - 1) &&
         value < std::ldexp(1.0, static_cast<int>(bits) - 1);
}

/// Reads `points` ascii records (one point per line, values in field order); with `last`, any
/// further non-empty line is an error (the header announced fewer points than the data holds).
void read_ascii_points(LineReader& reader, std::uint64_t points, const std::vector<Field>& fields,
                       const std::array<std::size_t, 3>& xyz, const ReadOptions& options,
                       PointCloud& cloud, bool last) {
  const std::string& name = reader.name();
  std::uint64_t values_per_point = 0;
  std::vector<std::uint64_t> first_value(fields.size());
  for (std::size_t i = 0; i < fields.size(); ++i) {
    first_value[i] = values_per_point;
    values_per_point = checked_add(values_per_point, fields[i].count, name, "the values per point");
  }
  std::string_view line;
  std::uint64_t read = 0;
  while (read < points && reader.next_line(&line)) {
    const auto values = words(line);
    if (values.empty()) continue;
    if (values.size() < values_per_point) {
      fail(name, "point " + std::to_string(read) + " (line " +
                     std::to_string(reader.line_number()) + ") has " +
                     std::to_string(values.size()) + " values, expected " +
                     std::to_string(values_per_point));
    }
    double p[3];
    for (int a = 0; a < 3; ++a) {
      const Field& f = fields[xyz[static_cast<std::size_t>(a)]];
      p[a] = parse_value(values[first_value[xyz[static_cast<std::size_t>(a)]]], name, read);
      if (f.kind != 'F' && std::isfinite(p[a]) && !fits_integer(p[a], f)) {
        fail(name, "point " + std::to_string(read) + ": " + f.name + " = " +
                       quote_bytes(values[first_value[xyz[static_cast<std::size_t>(a)]]]) +
                       " does not fit its type " + f.kind + std::to_string(f.size));
      }
    }
    add_point(cloud, p, read, name, options);
    ++read;
  }
  if (read < points) {
    fail(name, "truncated: header announces " + std::to_string(points) + " points, found " +
                   std::to_string(read));
  }
  while (last && reader.next_line(&line)) {
    if (!words(line).empty()) {
      fail(name, "line " + std::to_string(reader.line_number()) + ": data after the " +
                     std::to_string(points) + " points the header announces");
    }
  }
}

/// Reads `points` binary records of `record` bytes, in chunks.
void read_binary_points(LineReader& reader, std::uint64_t points, const std::vector<Field>& fields,
                        std::size_t record, const std::array<std::size_t, 3>& xyz,
                        const ReadOptions& options, PointCloud& cloud, bool last) {
  const std::string& name = reader.name();
  if (record == 0) fail(name, "empty point record");
  const std::optional<std::uint64_t> left = reader.remaining();
  if (left && *left / record < points) {
    fail(name, "truncated: header announces " + std::to_string(points) + " points of " +
                   std::to_string(record) + " bytes, the file holds " + std::to_string(*left) +
                   " bytes of data");
  }
  if (last && left && *left != points * record) {
    fail(name, "the file holds " + std::to_string(*left - points * record) + " bytes after the " +
                   std::to_string(points) +
                   " points the header announces (a header that lies about the count?)");
  }
  try {
    cloud.points.reserve(static_cast<std::size_t>(points));
  } catch (const std::bad_alloc&) {
    fail(name, "not enough memory for " + std::to_string(points) + " points");
  }
  const std::size_t per_chunk = std::max<std::size_t>(1, kChunkBytes / record);
  std::vector<char> chunk(per_chunk * record);
  std::uint64_t index = 0;
  while (index < points) {
    const std::size_t count =
        static_cast<std::size_t>(std::min<std::uint64_t>(per_chunk, points - index));
    const std::size_t want = count * record;
    if (reader.read(chunk.data(), want) != want) {
      fail(name, "truncated: the data ends within point " + std::to_string(index) + " of " +
                     std::to_string(points));
    }
    for (std::size_t k = 0; k < count; ++k, ++index) {
      const char* base = chunk.data() + k * record;
      double p[3];
      for (int a = 0; a < 3; ++a) {
        const Field& f = fields[xyz[static_cast<std::size_t>(a)]];
        p[a] = read_binary(base + f.offset, f);
      }
      add_point(cloud, p, index, name, options);
    }
  }
}

PointCloud read_pcd_from(ByteSource& source, const ReadOptions& options) {
  const std::string& name = source.name();
  LineReader reader(source);
  std::string_view line;
  std::vector<Field> fields;
  std::vector<std::uint64_t> sizes, counts;
  std::vector<char> types;
  std::uint64_t points = 0, width = 0, height = 0;
  bool have_points = false, have_width = false, have_height = false, any_line = false;
  std::string format;
  std::vector<std::string> seen;
  while (reader.next_line(&line)) {
    any_line = true;
    const auto w = words(line);
    if (w.empty() || w[0][0] == '#') continue;
    const std::string key(w[0]);
    const bool known = key == "VERSION" || key == "VIEWPOINT" || key == "WIDTH" ||
                       key == "HEIGHT" || key == "FIELDS" || key == "SIZE" || key == "TYPE" ||
                       key == "COUNT" || key == "POINTS" || key == "DATA";
    if (!known) fail(name, "unknown PCD header line " + quote_bytes(line));
    for (const std::string& s : seen) {
      if (s == key) fail(name, "header line " + key + " appears twice");
    }
    seen.push_back(key);
    const auto single = [&](const char* what) {
      if (w.size() != 2)
        fail(name, std::string("malformed ") + what + " line " + quote_bytes(line));
      return parse_count(w[1], name, what);
    };
    if (key == "VERSION" || key == "VIEWPOINT") {
      continue;
    } else if (key == "WIDTH") {
      width = single("WIDTH");
      have_width = true;
    } else if (key == "HEIGHT") {
      height = single("HEIGHT");
      have_height = true;
    } else if (key == "FIELDS") {
      for (std::size_t i = 1; i < w.size(); ++i) fields.push_back({std::string(w[i])});
    } else if (key == "SIZE") {
      for (std::size_t i = 1; i < w.size(); ++i) sizes.push_back(parse_count(w[i], name, "SIZE"));
    } else if (key == "TYPE") {
      for (std::size_t i = 1; i < w.size(); ++i) {
        if (w[i].size() != 1 || (w[i][0] != 'F' && w[i][0] != 'I' && w[i][0] != 'U'))
          fail(name, "unknown TYPE " + quote_bytes(w[i]));
        types.push_back(w[i][0]);
      }
    } else if (key == "COUNT") {
      for (std::size_t i = 1; i < w.size(); ++i) counts.push_back(parse_count(w[i], name, "COUNT"));
    } else if (key == "POINTS") {
      points = single("POINTS");
      have_points = true;
    } else {  // DATA
      if (w.size() != 2) fail(name, "malformed DATA line " + quote_bytes(line));
      format = std::string(w[1]);
      break;
    }
  }
  if (!any_line) fail(name, "empty file");
  if (format.empty()) fail(name, "not a PCD file (no DATA line)");
  if (fields.empty()) fail(name, "no FIELDS line");
  if (!have_points) fail(name, "no POINTS line");
  if (counts.empty()) counts.assign(fields.size(), 1);
  if (sizes.size() != fields.size() || types.size() != fields.size() ||
      counts.size() != fields.size()) {
    fail(name, "FIELDS, SIZE, TYPE and COUNT have different lengths (" +
                   std::to_string(fields.size()) + ", " + std::to_string(sizes.size()) + ", " +
                   std::to_string(types.size()) + ", " + std::to_string(counts.size()) + ")");
  }
  if (have_width && have_height &&
      checked_multiply(width, height, name, "WIDTH x HEIGHT") != points) {
    fail(name, "WIDTH " + std::to_string(width) + " x HEIGHT " + std::to_string(height) +
                   " does not equal POINTS " + std::to_string(points));
  }
  std::uint64_t record = 0;
  for (std::size_t i = 0; i < fields.size(); ++i) {
    if (counts[i] == 0 || sizes[i] == 0 || sizes[i] > 8) {
      fail(name, "field " + quote_bytes(fields[i].name) + " has a bad SIZE (" +
                     std::to_string(sizes[i]) + ") or COUNT (" + std::to_string(counts[i]) + ")");
    }
    const std::uint64_t offset = record;
    const std::uint64_t bytes = checked_multiply(
        sizes[i], counts[i], name, "the size of field " + quote_bytes(fields[i].name));
    record = checked_add(record, bytes, name, "the point record size");
    if (record > kMaxRecordBytes) {
      fail(name, "a point record of more than " + std::to_string(kMaxRecordBytes) +
                     " bytes (SIZE x COUNT summed over the fields)");
    }
    fields[i].offset = static_cast<std::size_t>(offset);
    fields[i].size = static_cast<std::size_t>(sizes[i]);
    fields[i].kind = types[i];
    fields[i].count = static_cast<std::size_t>(counts[i]);
  }
  const std::array<std::size_t, 3> xyz = xyz_fields(fields, name);
  check_point_count(points, name, options);
  PointCloud cloud;
  if (format == "ascii") {
    read_ascii_points(reader, points, fields, xyz, options, cloud, true);
  } else if (format == "binary") {
    read_binary_points(reader, points, fields, static_cast<std::size_t>(record), xyz, options,
                       cloud, true);
  } else if (format == "binary_compressed") {
    fail(name, "DATA binary_compressed is not supported (convert to binary or ascii)");
  } else {
    fail(name, "unknown DATA format " + quote_bytes(format));
  }
  return cloud;
}

PointCloud read_ply_from(ByteSource& source, const ReadOptions& options) {
  const std::string& name = source.name();
  LineReader reader(source);
  std::string_view line;
  if (!reader.next_line(&line)) fail(name, "empty file");
  if (line != "ply") fail(name, "not a PLY file (no 'ply' magic line)");
  std::string format;
  std::vector<Field> fields;
  std::uint64_t vertices = 0;
  bool in_vertex = false, seen_vertex = false, header_done = false, later_elements = false;
  std::uint64_t record = 0;
  while (reader.next_line(&line)) {
    const auto w = words(line);
    if (w.empty()) continue;
    if (w[0] == "end_header") {
      header_done = true;
      break;
    }
    if (w[0] == "comment" || w[0] == "obj_info") continue;
    if (w[0] == "format") {
      if (w.size() < 2) fail(name, "malformed format line " + quote_bytes(line));
      if (!format.empty()) fail(name, "the format line appears twice");
      format = std::string(w[1]);
    } else if (w[0] == "element") {
      if (w.size() != 3) fail(name, "malformed element line " + quote_bytes(line));
      in_vertex = w[1] == "vertex";
      if (in_vertex) {
        if (seen_vertex) fail(name, "the vertex element appears twice");
        vertices = parse_count(w[2], name, "the vertex count");
        seen_vertex = true;
      } else if (!seen_vertex) {
        fail(name, "element " + quote_bytes(w[1]) + " comes before the vertices (not supported)");
      } else {
        later_elements = parse_count(w[2], name, "the count of element " + quote_bytes(w[1])) > 0 ||
                         later_elements;
      }
    } else if (w[0] == "property") {
      if (!in_vertex) continue;
      if (w.size() >= 2 && w[1] == "list")
        fail(name, "list properties on vertices are not supported");
      if (w.size() != 3) fail(name, "malformed property line " + quote_bytes(line));
      const std::string_view t = w[1];
      Field f{std::string(w[2])};
      if (t == "float" || t == "float32") {
        f.kind = 'F';
        f.size = 4;
      } else if (t == "double" || t == "float64") {
        f.kind = 'F';
        f.size = 8;
      } else if (t == "char" || t == "int8") {
        f.kind = 'I';
        f.size = 1;
      } else if (t == "uchar" || t == "uint8") {
        f.kind = 'U';
        f.size = 1;
      } else if (t == "short" || t == "int16") {
        f.kind = 'I';
        f.size = 2;
      } else if (t == "ushort" || t == "uint16") {
        f.kind = 'U';
        f.size = 2;
      } else if (t == "int" || t == "int32") {
        f.kind = 'I';
        f.size = 4;
      } else if (t == "uint" || t == "uint32") {
        f.kind = 'U';
        f.size = 4;
      } else {
        fail(name, "unknown property type " + quote_bytes(t));
      }
      f.offset = static_cast<std::size_t>(record);
      record = checked_add(record, f.size, name, "the vertex record size");
      if (record > kMaxRecordBytes) {
        fail(name, "a vertex record of more than " + std::to_string(kMaxRecordBytes) + " bytes");
      }
      fields.push_back(f);
    } else {
      fail(name, "unknown PLY header line " + quote_bytes(line));
    }
  }
  if (!header_done) fail(name, "truncated header (no end_header)");
  if (!seen_vertex) fail(name, "no vertex element");
  const std::array<std::size_t, 3> xyz = xyz_fields(fields, name);
  if (format.empty()) fail(name, "no format line");
  check_point_count(vertices, name, options);
  PointCloud cloud;
  if (format == "ascii") {
    read_ascii_points(reader, vertices, fields, xyz, options, cloud, !later_elements);
  } else if (format == "binary_little_endian") {
    read_binary_points(reader, vertices, fields, static_cast<std::size_t>(record), xyz, options,
                       cloud, !later_elements);
  } else if (format == "binary_big_endian") {
    fail(name, "binary_big_endian PLY is not supported");
  } else {
    fail(name, "unknown PLY format " + quote_bytes(format));
  }
  return cloud;
}

}  // namespace

PointCloud read_pcd(const std::filesystem::path& path, const ReadOptions& options) {
  InputFile file(path, InputKind::kRegular);
  return read_pcd_from(file, options);
}

PointCloud parse_pcd(std::string_view bytes, const std::string& name, const ReadOptions& options) {
  MemorySource source(bytes, name);
  return read_pcd_from(source, options);
}

PointCloud read_ply(const std::filesystem::path& path, const ReadOptions& options) {
  InputFile file(path, InputKind::kRegular);
  return read_ply_from(file, options);
}

PointCloud parse_ply(std::string_view bytes, const std::string& name, const ReadOptions& options) {
  MemorySource source(bytes, name);
  return read_ply_from(source, options);
}

void write_pcd(const std::filesystem::path& path, const PointCloud& cloud, bool ascii) {
  write_file_atomically(path, [&](std::ostream& out) {
    out << "# .PCD v0.7 - written by carat\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F "
           "F\nCOUNT 1 1 1\n"
        << "WIDTH " << cloud.size() << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS "
        << cloud.size() << "\nDATA " << (ascii ? "ascii" : "binary") << "\n";
    if (ascii) {
      out.precision(9);
      for (const auto& p : cloud.points) out << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
    } else {
      for (const auto& p : cloud.points) out.write(reinterpret_cast<const char*>(p.data()), 12);
    }
  });
}

void write_ply(const std::filesystem::path& path, const PointCloud& cloud, bool ascii) {
  write_file_atomically(path, [&](std::ostream& out) {
    out << "ply\nformat " << (ascii ? "ascii" : "binary_little_endian")
        << " 1.0\ncomment written by carat\nelement vertex " << cloud.size()
        << "\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
    if (ascii) {
      out.precision(9);
      for (const auto& p : cloud.points) out << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
    } else {
      for (const auto& p : cloud.points) out.write(reinterpret_cast<const char*>(p.data()), 12);
    }
  });
}

PointCloud read_point_cloud(const std::filesystem::path& path, KittiFormat kitti_format,
                            const ReadOptions& options) {
  const std::string ext = path.extension().string();
  if (ext == ".pcd") return read_pcd(path, options);
  if (ext == ".ply") return read_ply(path, options);
  if (ext == ".bin") return read_kitti_bin(path, kitti_format, options);
  throw Error(path.string() + ": unsupported file type " + quote_bytes(ext) +
              " (expected .pcd, .ply or .bin)");
}

}  // namespace carat
