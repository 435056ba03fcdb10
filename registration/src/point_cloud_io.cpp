#include "carat/registration/point_cloud_io.hpp"

#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "carat/solver/atomic_file.hpp"
#include "carat/solver/error.hpp"

namespace carat {
namespace {

/// A scalar field of a binary record: its byte offset, size and kind.
struct Field {
  std::string name;
  std::size_t offset = 0;
  std::size_t size = 0;
  char kind = 'F';  // 'F' float, 'I' signed, 'U' unsigned
  std::size_t count = 1;
};

std::vector<char> read_all(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw Error(name + ": no such file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(name + ": cannot open for reading");
  std::vector<char> data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (data.empty()) throw Error(name + ": empty file");
  return data;
}

/// Reads one header line starting at `pos` (advances past the newline); false at the end.
bool next_line(const std::vector<char>& data, std::size_t& pos, std::string* line) {
  if (pos >= data.size()) return false;
  const std::size_t start = pos;
  while (pos < data.size() && data[pos] != '\n') ++pos;
  line->assign(data.data() + start, pos - start);
  if (!line->empty() && line->back() == '\r') line->pop_back();
  if (pos < data.size()) ++pos;
  return true;
}

std::vector<std::string> words(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> out;
  for (std::string w; in >> w;) out.push_back(w);
  return out;
}

double read_binary(const char* p, const Field& f, const std::string& name) {
  switch (f.kind) {
    case 'F':
      if (f.size == 4) {
        float v;
        std::memcpy(&v, p, 4);
        return v;
      }
      if (f.size == 8) {
        double v;
        std::memcpy(&v, p, 8);
        return v;
      }
      break;
    case 'I':
      if (f.size == 1) return static_cast<std::int8_t>(*p);
      if (f.size == 2) {
        std::int16_t v;
        std::memcpy(&v, p, 2);
        return v;
      }
      if (f.size == 4) {
        std::int32_t v;
        std::memcpy(&v, p, 4);
        return v;
      }
      break;
    case 'U':
      if (f.size == 1) return static_cast<std::uint8_t>(*p);
      if (f.size == 2) {
        std::uint16_t v;
        std::memcpy(&v, p, 2);
        return v;
      }
      if (f.size == 4) {
        std::uint32_t v;
        std::memcpy(&v, p, 4);
        return v;
      }
      break;
  }
  throw Error(name + ": field '" + f.name + "' has an unsupported type " + f.kind +
              std::to_string(f.size));
}

void add_point(PointCloud& cloud, const double xyz[3], std::size_t index, const std::string& name,
               const ReadOptions& options) {
  if (!std::isfinite(xyz[0]) || !std::isfinite(xyz[1]) || !std::isfinite(xyz[2])) {
    if (options.drop_non_finite) return;
    throw Error(name + ": point " + std::to_string(index) + " is not finite");
  }
  cloud.points.emplace_back(static_cast<float>(xyz[0]), static_cast<float>(xyz[1]),
                            static_cast<float>(xyz[2]));
}

std::size_t parse_count(const std::string& text, const std::string& name, const char* what) {
  std::size_t value = 0;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || ptr != text.data() + text.size())
    throw Error(name + ": cannot read " + what + " from '" + text + "'");
  return value;
}

double parse_number(const std::string& text, const std::string& name, std::size_t point) {
  double value = 0.0;
  const char* begin = text.data();
  if (!text.empty() && text[0] == '+') ++begin;
  const auto [ptr, ec] = std::from_chars(begin, text.data() + text.size(), value);
  if (ec != std::errc() || ptr != text.data() + text.size()) {
    if (text == "nan" || text == "-nan" || text == "NaN") return std::nan("");
    throw Error(name + ": point " + std::to_string(point) + ": cannot read a number from '" + text +
                "'");
  }
  return value;
}

/// Positions of the x, y, z fields, or an error naming the missing one.
std::array<int, 3> xyz_fields(const std::vector<Field>& fields, const std::string& name) {
  std::array<int, 3> out{-1, -1, -1};
  const char* names[3] = {"x", "y", "z"};
  for (std::size_t i = 0; i < fields.size(); ++i) {
    for (int a = 0; a < 3; ++a) {
      if (fields[i].name == names[a]) out[static_cast<std::size_t>(a)] = static_cast<int>(i);
    }
  }
  for (int a = 0; a < 3; ++a) {
    if (out[static_cast<std::size_t>(a)] < 0) throw Error(name + ": no '" + names[a] + "' field");
    if (fields[static_cast<std::size_t>(out[static_cast<std::size_t>(a)])].count != 1) {
      throw Error(name + ": field '" + names[a] + "' must have COUNT 1");
    }
  }
  return out;
}

/// Reads `points` records of ascii text (one point per line, values in field order).
void read_ascii_points(const std::vector<char>& data, std::size_t pos, std::size_t points,
                       const std::vector<Field>& fields, const std::array<int, 3>& xyz,
                       const std::string& name, const ReadOptions& options, PointCloud& cloud) {
  std::size_t values_per_point = 0;
  std::vector<std::size_t> first_value(fields.size());
  for (std::size_t i = 0; i < fields.size(); ++i) {
    first_value[i] = values_per_point;
    values_per_point += fields[i].count;
  }
  std::string line;
  std::size_t read = 0;
  while (read < points && next_line(data, pos, &line)) {
    const auto values = words(line);
    if (values.empty()) continue;
    if (values.size() < values_per_point) {
      throw Error(name + ": point " + std::to_string(read) + " has " +
                  std::to_string(values.size()) + " values, expected " +
                  std::to_string(values_per_point));
    }
    double p[3];
    for (int a = 0; a < 3; ++a)
      p[a] = parse_number(
          values[first_value[static_cast<std::size_t>(xyz[static_cast<std::size_t>(a)])]], name,
          read);
    add_point(cloud, p, read, name, options);
    ++read;
  }
  if (read < points) {
    throw Error(name + ": truncated: header announces " + std::to_string(points) +
                " points, found " + std::to_string(read));
  }
}

void read_binary_points(const std::vector<char>& data, std::size_t pos, std::size_t points,
                        const std::vector<Field>& fields, std::size_t record,
                        const std::array<int, 3>& xyz, const std::string& name,
                        const ReadOptions& options, PointCloud& cloud) {
  if (record == 0) throw Error(name + ": empty point record");
  if ((data.size() - pos) / record < points) {
    throw Error(name + ": truncated: header announces " + std::to_string(points) + " points of " +
                std::to_string(record) + " bytes, the file holds " +
                std::to_string(data.size() - pos) + " bytes of data");
  }
  cloud.points.reserve(points);
  for (std::size_t i = 0; i < points; ++i) {
    const char* base = data.data() + pos + i * record;
    double p[3];
    for (int a = 0; a < 3; ++a) {
      const Field& f = fields[static_cast<std::size_t>(xyz[static_cast<std::size_t>(a)])];
      p[a] = read_binary(base + f.offset, f, name);
    }
    add_point(cloud, p, i, name, options);
  }
}

}  // namespace

PointCloud read_pcd(const std::filesystem::path& path, const ReadOptions& options) {
  const std::string name = path.string();
  const std::vector<char> data = read_all(path);
  std::size_t pos = 0;
  std::string line;
  std::vector<Field> fields;
  std::vector<std::size_t> sizes, counts;
  std::vector<char> types;
  std::size_t points = 0;
  bool have_points = false;
  std::string format;
  while (next_line(data, pos, &line)) {
    const auto w = words(line);
    if (w.empty() || w[0][0] == '#') continue;
    const std::string& key = w[0];
    if (key == "VERSION" || key == "VIEWPOINT" || key == "WIDTH" || key == "HEIGHT") {
      continue;
    } else if (key == "FIELDS") {
      fields.clear();
      for (std::size_t i = 1; i < w.size(); ++i) fields.push_back({w[i]});
    } else if (key == "SIZE") {
      for (std::size_t i = 1; i < w.size(); ++i) sizes.push_back(parse_count(w[i], name, "SIZE"));
    } else if (key == "TYPE") {
      for (std::size_t i = 1; i < w.size(); ++i) {
        if (w[i].size() != 1 || (w[i][0] != 'F' && w[i][0] != 'I' && w[i][0] != 'U'))
          throw Error(name + ": unknown TYPE '" + w[i] + "'");
        types.push_back(w[i][0]);
      }
    } else if (key == "COUNT") {
      for (std::size_t i = 1; i < w.size(); ++i) counts.push_back(parse_count(w[i], name, "COUNT"));
    } else if (key == "POINTS") {
      if (w.size() != 2) throw Error(name + ": malformed POINTS line");
      points = parse_count(w[1], name, "POINTS");
      have_points = true;
    } else if (key == "DATA") {
      if (w.size() != 2) throw Error(name + ": malformed DATA line");
      format = w[1];
      break;
    } else {
      throw Error(name + ": unknown PCD header line '" + line.substr(0, 40) + "'");
    }
  }
  if (format.empty()) throw Error(name + ": not a PCD file (no DATA line)");
  if (fields.empty()) throw Error(name + ": no FIELDS line");
  if (!have_points) throw Error(name + ": no POINTS line");
  if (counts.empty()) counts.assign(fields.size(), 1);
  if (sizes.size() != fields.size() || types.size() != fields.size() ||
      counts.size() != fields.size()) {
    throw Error(name + ": FIELDS, SIZE, TYPE and COUNT have different lengths");
  }
  std::size_t record = 0;
  for (std::size_t i = 0; i < fields.size(); ++i) {
    fields[i].offset = record;
    fields[i].size = sizes[i];
    fields[i].kind = types[i];
    fields[i].count = counts[i];
    if (counts[i] == 0 || sizes[i] == 0 || sizes[i] > 8)
      throw Error(name + ": field '" + fields[i].name + "' has a bad SIZE or COUNT");
    record += sizes[i] * counts[i];
  }
  const std::array<int, 3> xyz = xyz_fields(fields, name);
  PointCloud cloud;
  if (format == "ascii") {
    read_ascii_points(data, pos, points, fields, xyz, name, options, cloud);
  } else if (format == "binary") {
    read_binary_points(data, pos, points, fields, record, xyz, name, options, cloud);
  } else if (format == "binary_compressed") {
    throw Error(name + ": DATA binary_compressed is not supported (convert to binary or ascii)");
  } else {
    throw Error(name + ": unknown DATA format '" + format + "'");
  }
  return cloud;
}

PointCloud read_ply(const std::filesystem::path& path, const ReadOptions& options) {
  const std::string name = path.string();
  const std::vector<char> data = read_all(path);
  std::size_t pos = 0;
  std::string line;
  if (!next_line(data, pos, &line) || line != "ply")
    throw Error(name + ": not a PLY file (no 'ply' magic line)");
  std::string format;
  std::vector<Field> fields;
  std::size_t vertices = 0;
  bool in_vertex = false, seen_vertex = false, header_done = false;
  std::size_t record = 0;
  while (next_line(data, pos, &line)) {
    const auto w = words(line);
    if (w.empty()) continue;
    if (w[0] == "end_header") {
      header_done = true;
      break;
    }
    if (w[0] == "comment" || w[0] == "obj_info") continue;
    if (w[0] == "format") {
      if (w.size() < 2) throw Error(name + ": malformed format line");
      format = w[1];
    } else if (w[0] == "element") {
      if (w.size() != 3) throw Error(name + ": malformed element line '" + line + "'");
      in_vertex = w[1] == "vertex";
      if (in_vertex) {
        vertices = parse_count(w[2], name, "the vertex count");
        seen_vertex = true;
      } else if (!seen_vertex) {
        throw Error(name + ": element '" + w[1] + "' comes before the vertices (not supported)");
      }
    } else if (w[0] == "property") {
      if (!in_vertex) continue;
      if (w.size() >= 2 && w[1] == "list")
        throw Error(name + ": list properties on vertices are not supported");
      if (w.size() != 3) throw Error(name + ": malformed property line '" + line + "'");
      const std::string& t = w[1];
      Field f{w[2]};
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
      } else
        throw Error(name + ": unknown property type '" + t + "'");
      f.offset = record;
      record += f.size;
      fields.push_back(f);
    } else {
      throw Error(name + ": unknown PLY header line '" + line.substr(0, 40) + "'");
    }
  }
  if (!header_done) throw Error(name + ": truncated header (no end_header)");
  if (!seen_vertex) throw Error(name + ": no vertex element");
  const std::array<int, 3> xyz = xyz_fields(fields, name);
  PointCloud cloud;
  if (format == "ascii") {
    read_ascii_points(data, pos, vertices, fields, xyz, name, options, cloud);
  } else if (format == "binary_little_endian") {
    read_binary_points(data, pos, vertices, fields, record, xyz, name, options, cloud);
  } else if (format == "binary_big_endian") {
    throw Error(name + ": binary_big_endian PLY is not supported");
  } else {
    throw Error(name + ": unknown PLY format '" + format + "'");
  }
  return cloud;
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
  throw Error(path.string() + ": unsupported file type '" + ext +
              "' (expected .pcd, .ply or .bin)");
}

}  // namespace carat
