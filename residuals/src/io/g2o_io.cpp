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
#include "carat/solver/se2.hpp"

namespace carat {
namespace {

/// Whether c separates tokens: the C locale's white space (std::isspace's set there), tested
/// inline (a library call per character was most of the parse) and the same in any locale.
constexpr bool is_blank(char c) {
  return c == ' ' || c == '\t' || c == '\n' || c == '\v' || c == '\f' || c == '\r';
}

/// The white-space separated tokens of `line` into *tokens (cleared first; its storage is kept
/// from line to line).
void split(std::string_view line, std::vector<std::string_view>* tokens) {
  tokens->clear();
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_blank(line[i])) ++i;
    const std::size_t start = i;
    while (i < line.size() && !is_blank(line[i])) ++i;
    if (i > start) tokens->push_back(line.substr(start, i - start));
  }
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

  Eigen::Isometry2d pose_se2(const std::vector<std::string_view>& t, std::size_t first) const {
    return se2::make(number(t[first], "x"), number(t[first + 1], "y"),
                     number(t[first + 2], "theta"));
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

template <typename Matrix>
bool is_symmetric(const Matrix& m) {
  const double scale = std::max(1.0, m.cwiseAbs().maxCoeff());
  return (m - m.transpose()).cwiseAbs().maxCoeff() <= 1e-9 * scale;
}

/// V max(Lambda, 1e-9 lambda_max) V^T of a symmetric matrix (see G2oReadOptions).
template <typename Matrix>
Matrix nearest_positive_definite(const Matrix& information, const LineParser& p) {
  const Eigen::SelfAdjointEigenSolver<Matrix> eigen(information);
  if (eigen.info() != Eigen::Success) p.fail("information matrix: eigen-decomposition failed");
  const double largest = eigen.eigenvalues().maxCoeff();
  if (!(largest > 0.0)) p.fail("information matrix has no positive eigenvalue; cannot repair it");
  const typename Eigen::SelfAdjointEigenSolver<Matrix>::RealVectorType clamped =
      eigen.eigenvalues().cwiseMax(1e-9 * largest);
  Matrix repaired = eigen.eigenvectors() * clamped.asDiagonal() * eigen.eigenvectors().transpose();
  repaired = 0.5 * (repaired + repaired.transpose()).eval();
  try {
    (void)sqrt_information(repaired, "information matrix");
  } catch (const Error& error) {
    p.fail(std::string(error.what()) + " (even after repair)");
  }
  return repaired;
}

/// Reads the upper triangle of an n x n information matrix from tokens[first...] and checks it
/// (repairing it when asked).
template <typename Matrix>
Matrix read_information(const LineParser& p, const std::vector<std::string_view>& tokens,
                        std::size_t first, const G2oReadOptions& options, G2oReadReport* report,
                        std::size_t line) {
  Matrix information;
  std::size_t k = first;
  for (int r = 0; r < information.rows(); ++r) {
    for (int c = r; c < information.cols(); ++c) {
      information(r, c) = information(c, r) = p.number(tokens[k++], "information entry");
    }
  }
  try {
    (void)sqrt_information(information, "information matrix");
  } catch (const Error& error) {
    if (options.information != InformationRepair::kNearest || !is_symmetric(information)) {
      p.fail(error.what());
    }
    information = nearest_positive_definite(information, p);
    if (report) report->repaired_lines.push_back(line);
  }
  return information;
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

/// Which dimension a reader expects.
enum class Dimension { kAny, k2d, k3d };

const char* dimension_name(Dimension d) { return d == Dimension::k2d ? "2D" : "3D"; }

G2oGraph read_g2o_lines(LineReader& reader, Dimension expected, const G2oReadOptions& options,
                        G2oReadReport* report) {
  const std::string& name = reader.name();
  if (report) report->repaired_lines.clear();
  PoseGraph graph;
  PoseGraphSE2 graph_se2;
  Dimension dimension = expected;
  std::size_t dimension_line = 0;  // the record that decided the dimension (0: the caller)
  std::string dimension_tag;
  std::unordered_map<std::int64_t, std::size_t> vertex_line;
  std::vector<std::size_t> edge_lines;
  std::vector<std::int64_t> fixed;
  std::string_view text;
  std::vector<std::string_view> tokens;
  while (reader.next_line(&text)) {
    const std::size_t line = reader.line_number();
    const auto hash = text.find('#');
    split(text.substr(0, hash), &tokens);
    if (tokens.empty()) continue;
    const LineParser p(name, line);
    const std::string_view tag = tokens[0];
    const bool is_3d = tag == "VERTEX_SE3:QUAT" || tag == "EDGE_SE3:QUAT";
    const bool is_2d = tag == "VERTEX_SE2" || tag == "EDGE_SE2";
    if (is_3d || is_2d) {
      const Dimension record = is_2d ? Dimension::k2d : Dimension::k3d;
      if (dimension == Dimension::kAny) {
        dimension = record;
        dimension_line = line;
        dimension_tag = tag;
      } else if (dimension != record) {
        const std::string what =
            std::string(dimension_name(record)) + " record " + std::string(tag);
        if (dimension_line == 0) {
          p.fail(what + " where a " + dimension_name(dimension) + " graph is expected");
        }
        p.fail(what + " in a " + dimension_name(dimension) + " graph (line " +
               std::to_string(dimension_line) + " holds " + dimension_tag + ")");
      }
    }
    const auto add_vertex_line = [&](std::int64_t id) {
      if (!vertex_line.emplace(id, line).second) {
        p.fail("vertex " + std::to_string(id) + " was already defined on line " +
               std::to_string(vertex_line[id]));
      }
    };
    const auto read_ends = [&](std::int64_t* from, std::int64_t* to) {
      *from = p.id(tokens[1]);
      *to = p.id(tokens[2]);
      if (*from == *to) p.fail("edge joins vertex " + std::to_string(*from) + " to itself");
    };
    if (tag == "VERTEX_SE3:QUAT") {
      expect_count(p, tokens, 8, "VERTEX_SE3:QUAT");
      PoseGraph::Vertex& v = graph.vertices.emplace_back();  // a failed line ends the read
      v.id = p.id(tokens[1]);
      v.T_world_vertex = p.pose(tokens, 2);
      add_vertex_line(v.id);
    } else if (tag == "EDGE_SE3:QUAT") {
      expect_count(p, tokens, 30, "EDGE_SE3:QUAT");
      PoseGraph::Edge& e = graph.edges.emplace_back();
      read_ends(&e.from, &e.to);
      e.T_from_to = p.pose(tokens, 3);
      e.information = read_information<se3::Matrix6d>(p, tokens, 10, options, report, line);
      edge_lines.push_back(line);
    } else if (tag == "VERTEX_SE2") {
      expect_count(p, tokens, 4, "VERTEX_SE2");
      PoseGraphSE2::Vertex v;
      v.id = p.id(tokens[1]);
      v.T_world_vertex = p.pose_se2(tokens, 2);
      add_vertex_line(v.id);
      graph_se2.vertices.push_back(v);
    } else if (tag == "EDGE_SE2") {
      expect_count(p, tokens, 11, "EDGE_SE2");
      PoseGraphSE2::Edge e;
      read_ends(&e.from, &e.to);
      e.T_from_to = p.pose_se2(tokens, 3);
      e.information = read_information<Eigen::Matrix3d>(p, tokens, 6, options, report, line);
      graph_se2.edges.push_back(e);
      edge_lines.push_back(line);
    } else if (tag == "FIX") {
      if (tokens.size() < 2) p.fail("FIX needs at least one vertex id");
      for (std::size_t k = 1; k < tokens.size(); ++k) fixed.push_back(p.id(tokens[k]));
    } else {
      p.fail("unknown record " + quote_bytes(tag));
    }
  }
  const auto check_fixed = [&] {
    for (std::int64_t id : fixed) {
      if (!vertex_line.count(id))
        throw Error(name + ": FIX names vertex " + std::to_string(id) + ", which is not defined");
    }
  };
  const auto check_edges = [&](const auto& edges) {
    for (std::size_t e = 0; e < edges.size(); ++e) {
      for (std::int64_t id : {edges[e].from, edges[e].to}) {
        if (!vertex_line.count(id)) {
          throw Error(name + ":" + std::to_string(edge_lines[e]) + ": edge names vertex " +
                      std::to_string(id) + ", which is not defined");
        }
      }
    }
  };
  if (dimension == Dimension::k2d) {
    if (graph_se2.vertices.empty()) {
      if (graph_se2.edges.empty())
        throw Error(name + ": no VERTEX_SE2 or EDGE_SE2 records (empty or not a 2D g2o file)");
      compose_odometry(&graph_se2, name);
      for (const auto& v : graph_se2.vertices) vertex_line.emplace(v.id, 0);
    }
    check_edges(graph_se2.edges);
    check_fixed();
    graph_se2.fixed = std::move(fixed);
    return graph_se2;
  }
  if (graph.vertices.empty())
    throw Error(name + ": no VERTEX_SE3:QUAT records (empty or not a 3D g2o file)");
  check_edges(graph.edges);
  check_fixed();
  graph.fixed = std::move(fixed);
  return graph;
}

}  // namespace

PoseGraph parse_g2o(std::istream& in, const std::string& name, const G2oReadOptions& options,
                    G2oReadReport* report) {
  StreamSource source(in, name);
  LineReader reader(source);
  return std::get<PoseGraph>(read_g2o_lines(reader, Dimension::k3d, options, report));
}

PoseGraph parse_g2o(std::string_view text, const std::string& name, const G2oReadOptions& options,
                    G2oReadReport* report) {
  MemorySource source(text, name);
  LineReader reader(source);
  return std::get<PoseGraph>(read_g2o_lines(reader, Dimension::k3d, options, report));
}

PoseGraph read_g2o(const std::filesystem::path& path, const G2oReadOptions& options,
                   G2oReadReport* report) {
  InputFile file(path, InputKind::kStreamable);
  LineReader reader(file);
  return std::get<PoseGraph>(read_g2o_lines(reader, Dimension::k3d, options, report));
}

PoseGraphSE2 read_g2o_se2(const std::filesystem::path& path, const G2oReadOptions& options,
                          G2oReadReport* report) {
  InputFile file(path, InputKind::kStreamable);
  LineReader reader(file);
  return std::get<PoseGraphSE2>(read_g2o_lines(reader, Dimension::k2d, options, report));
}

PoseGraphSE2 parse_g2o_se2(std::string_view text, const std::string& name,
                           const G2oReadOptions& options, G2oReadReport* report) {
  MemorySource source(text, name);
  LineReader reader(source);
  return std::get<PoseGraphSE2>(read_g2o_lines(reader, Dimension::k2d, options, report));
}

G2oGraph read_g2o_any(const std::filesystem::path& path, const G2oReadOptions& options,
                      G2oReadReport* report) {
  InputFile file(path, InputKind::kStreamable);
  LineReader reader(file);
  return read_g2o_lines(reader, Dimension::kAny, options, report);
}

G2oGraph parse_g2o_any(std::string_view text, const std::string& name,
                       const G2oReadOptions& options, G2oReadReport* report) {
  MemorySource source(text, name);
  LineReader reader(source);
  return read_g2o_lines(reader, Dimension::kAny, options, report);
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

void write_g2o(std::ostream& out, const PoseGraphSE2& graph) {
  char buffer[128];
  const auto put_pose = [&](const Eigen::Isometry2d& T) {
    std::snprintf(buffer, sizeof(buffer), " %.17g %.17g %.17g", T.translation().x(),
                  T.translation().y(), se2::angle(T));
    out << buffer;
  };
  for (const auto& v : graph.vertices) {
    out << "VERTEX_SE2 " << v.id;
    put_pose(v.T_world_vertex);
    out << '\n';
  }
  for (const auto& e : graph.edges) {
    out << "EDGE_SE2 " << e.from << ' ' << e.to;
    put_pose(e.T_from_to);
    for (int r = 0; r < 3; ++r) {
      for (int c = r; c < 3; ++c) {
        std::snprintf(buffer, sizeof(buffer), " %.17g", e.information(r, c));
        out << buffer;
      }
    }
    out << '\n';
  }
  for (std::int64_t id : graph.fixed) out << "FIX " << id << '\n';
}

void write_g2o(const std::filesystem::path& path, const PoseGraphSE2& graph) {
  write_file_atomically(path, [&](std::ostream& out) { write_g2o(out, graph); });
}

}  // namespace carat
