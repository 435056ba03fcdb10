#include "carat/residuals/io/g2o_io.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "carat/base/atomic_file.hpp"
#include "carat/base/error.hpp"
#include "carat/base/input_file.hpp"
#include "carat/residuals/pose_prior_block.hpp"

namespace carat {
namespace {

std::vector<std::string_view> split(std::string_view line) {
  std::vector<std::string_view> tokens;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    const std::size_t start = i;
    while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    if (i > start) tokens.push_back(line.substr(start, i - start));
  }
  return tokens;
}

class LineParser {
 public:
  LineParser(const std::string& name, std::size_t line) : name_(name), line_(line) {}

  [[noreturn]] void fail(const std::string& problem) const {
    throw Error(name_ + ":" + std::to_string(line_) + ": " + problem);
  }

  double number(std::string_view token, const char* what) const {
    double value = 0.0;
    const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
    if (ec != std::errc() || ptr != token.data() + token.size()) {
      if (ec == std::errc::result_out_of_range && ptr == token.data() + token.size()) {
        fail(std::string(what) + " " + quote_bytes(token) + " is out of range");
      }
      fail(std::string("cannot read ") + what + " from " + quote_bytes(token));
    }
    if (!std::isfinite(value)) fail(std::string(what) + " is not finite");
    return value;
  }

  std::int64_t id(std::string_view token) const {
    std::int64_t value = 0;
    const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
    if (ec != std::errc() || ptr != token.data() + token.size()) {
      fail("cannot read a vertex id (an integer in [-2^63, 2^63)) from " + quote_bytes(token));
    }
    return value;
  }

  Eigen::Isometry3d pose(const std::vector<std::string_view>& t, std::size_t first) const {
    const Eigen::Vector3d translation(number(t[first], "x"), number(t[first + 1], "y"),
                                      number(t[first + 2], "z"));
    Eigen::Quaterniond q(number(t[first + 6], "qw"), number(t[first + 3], "qx"),
                         number(t[first + 4], "qy"), number(t[first + 5], "qz"));
    const double norm = q.norm();
    if (!(norm > 1e-6)) fail("quaternion has zero length");
    if (std::abs(norm - 1.0) > 1e-3) {
      fail("quaternion is not normalized (length " + std::to_string(norm) + ")");
    }
    return se3::make(q, translation);
  }

 private:
  const std::string& name_;
  std::size_t line_;
};

void expect_count(const LineParser& p, const std::vector<std::string_view>& t, std::size_t count,
                  const char* tag) {
  if (t.size() != count + 1) {
    p.fail(std::string(tag) + " needs " + std::to_string(count) + " numbers, found " +
           std::to_string(t.size() - 1));
  }
}

bool is_symmetric(const se3::Matrix6d& m) {
  const double scale = std::max(1.0, m.cwiseAbs().maxCoeff());
  return (m - m.transpose()).cwiseAbs().maxCoeff() <= 1e-9 * scale;
}

/// V max(Lambda, 1e-9 lambda_max) V^T of a symmetric matrix (see G2oReadOptions).
se3::Matrix6d nearest_positive_definite(const se3::Matrix6d& information, const LineParser& p) {
  const Eigen::SelfAdjointEigenSolver<se3::Matrix6d> eigen(information);
  if (eigen.info() != Eigen::Success) p.fail("information matrix: eigen-decomposition failed");
  const double largest = eigen.eigenvalues().maxCoeff();
  if (!(largest > 0.0)) p.fail("information matrix has no positive eigenvalue; cannot repair it");
  const se3::Vector6d clamped = eigen.eigenvalues().cwiseMax(1e-9 * largest);
  se3::Matrix6d repaired =
      eigen.eigenvectors() * clamped.asDiagonal() * eigen.eigenvectors().transpose();
  repaired = 0.5 * (repaired + repaired.transpose()).eval();
  try {
    (void)sqrt_information(repaired, "information matrix");
  } catch (const Error& error) {
    p.fail(std::string(error.what()) + " (even after repair)");
  }
  return repaired;
}

}  // namespace

namespace {

/// A std::istream read like a file.
class StreamSource final : public ByteSource {
 public:
  StreamSource(std::istream& in, const std::string& name) : in_(in), name_(name) {}
  std::size_t read(char* out, std::size_t n) override {
    in_.read(out, static_cast<std::streamsize>(n));
    if (in_.bad()) throw Error(name_ + ": read error");
    return static_cast<std::size_t>(in_.gcount());
  }
  std::optional<std::uint64_t> remaining() const override { return std::nullopt; }
  const std::string& name() const override { return name_; }

 private:
  std::istream& in_;
  const std::string& name_;
};

PoseGraph read_g2o_lines(LineReader& reader, const G2oReadOptions& options, G2oReadReport* report) {
  const std::string& name = reader.name();
  if (report) report->repaired_lines.clear();
  PoseGraph graph;
  std::unordered_map<std::int64_t, std::size_t> vertex_line;
  std::vector<std::size_t> edge_lines;
  std::string_view text;
  while (reader.next_line(&text)) {
    const std::size_t line = reader.line_number();
    const auto hash = text.find('#');
    const auto tokens = split(text.substr(0, hash));
    if (tokens.empty()) continue;
    const LineParser p(name, line);
    const std::string_view tag = tokens[0];
    if (tag == "VERTEX_SE3:QUAT") {
      expect_count(p, tokens, 8, "VERTEX_SE3:QUAT");
      PoseGraph::Vertex v;
      v.id = p.id(tokens[1]);
      v.T_world_vertex = p.pose(tokens, 2);
      if (!vertex_line.emplace(v.id, line).second) {
        p.fail("vertex " + std::to_string(v.id) + " was already defined on line " +
               std::to_string(vertex_line[v.id]));
      }
      graph.vertices.push_back(v);
    } else if (tag == "EDGE_SE3:QUAT") {
      expect_count(p, tokens, 30, "EDGE_SE3:QUAT");
      PoseGraph::Edge e;
      e.from = p.id(tokens[1]);
      e.to = p.id(tokens[2]);
      if (e.from == e.to) p.fail("edge joins vertex " + std::to_string(e.from) + " to itself");
      e.T_from_to = p.pose(tokens, 3);
      std::size_t k = 10;
      for (int r = 0; r < 6; ++r) {
        for (int c = r; c < 6; ++c) {
          e.information(r, c) = e.information(c, r) = p.number(tokens[k++], "information entry");
        }
      }
      try {
        (void)sqrt_information(e.information, "information matrix");
      } catch (const Error& error) {
        if (options.information != InformationRepair::kNearest || !is_symmetric(e.information)) {
          p.fail(error.what());
        }
        e.information = nearest_positive_definite(e.information, p);
        if (report) report->repaired_lines.push_back(line);
      }
      graph.edges.push_back(e);
      edge_lines.push_back(line);
    } else if (tag == "FIX") {
      if (tokens.size() < 2) p.fail("FIX needs at least one vertex id");
      for (std::size_t k = 1; k < tokens.size(); ++k) graph.fixed.push_back(p.id(tokens[k]));
    } else if (tag == "VERTEX_SE2" || tag == "EDGE_SE2") {
      p.fail("2D records (" + std::string(tag) +
             ") are not supported; carat reads 3D graphs (VERTEX_SE3:QUAT / EDGE_SE3:QUAT)");
    } else {
      p.fail("unknown record " + quote_bytes(tag));
    }
  }
  if (graph.vertices.empty())
    throw Error(name + ": no VERTEX_SE3:QUAT records (empty or not a 3D g2o file)");
  for (std::size_t e = 0; e < graph.edges.size(); ++e) {
    for (std::int64_t id : {graph.edges[e].from, graph.edges[e].to}) {
      if (!vertex_line.count(id)) {
        throw Error(name + ":" + std::to_string(edge_lines[e]) + ": edge names vertex " +
                    std::to_string(id) + ", which is not defined");
      }
    }
  }
  for (std::int64_t id : graph.fixed) {
    if (!vertex_line.count(id))
      throw Error(name + ": FIX names vertex " + std::to_string(id) + ", which is not defined");
  }
  return graph;
}

}  // namespace

PoseGraph parse_g2o(std::istream& in, const std::string& name, const G2oReadOptions& options,
                    G2oReadReport* report) {
  StreamSource source(in, name);
  LineReader reader(source);
  return read_g2o_lines(reader, options, report);
}

PoseGraph parse_g2o(std::string_view text, const std::string& name, const G2oReadOptions& options,
                    G2oReadReport* report) {
  MemorySource source(text, name);
  LineReader reader(source);
  return read_g2o_lines(reader, options, report);
}

PoseGraph read_g2o(const std::filesystem::path& path, const G2oReadOptions& options,
                   G2oReadReport* report) {
  InputFile file(path, InputKind::kStreamable);
  LineReader reader(file);
  return read_g2o_lines(reader, options, report);
}

void write_g2o(std::ostream& out, const PoseGraph& graph) {
  char buffer[128];
  const auto put_pose = [&](const Eigen::Isometry3d& T) {
    const Eigen::Quaterniond q(T.linear());
    const Eigen::Vector3d& t = T.translation();
    std::snprintf(buffer, sizeof(buffer), " %.17g %.17g %.17g", t.x(), t.y(), t.z());
    out << buffer;
    std::snprintf(buffer, sizeof(buffer), " %.17g %.17g %.17g %.17g", q.x(), q.y(), q.z(), q.w());
    out << buffer;
  };
  for (const auto& v : graph.vertices) {
    out << "VERTEX_SE3:QUAT " << v.id;
    put_pose(v.T_world_vertex);
    out << '\n';
  }
  for (const auto& e : graph.edges) {
    out << "EDGE_SE3:QUAT " << e.from << ' ' << e.to;
    put_pose(e.T_from_to);
    for (int r = 0; r < 6; ++r) {
      for (int c = r; c < 6; ++c) {
        std::snprintf(buffer, sizeof(buffer), " %.17g", e.information(r, c));
        out << buffer;
      }
    }
    out << '\n';
  }
  for (std::int64_t id : graph.fixed) out << "FIX " << id << '\n';
}

void write_g2o(const std::filesystem::path& path, const PoseGraph& graph) {
  write_file_atomically(path, [&](std::ostream& out) { write_g2o(out, graph); });
}

}  // namespace carat
