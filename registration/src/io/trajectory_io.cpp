#include "carat/registration/io/trajectory_io.hpp"

#include <Eigen/SVD>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <unordered_map>
#include <unordered_set>

#include "carat/base/atomic_file.hpp"
#include "carat/base/error.hpp"
#include "carat/base/input_file.hpp"

namespace carat {
namespace {

constexpr double kRotationTolerance = 1e-3;    // |R^T R - I| (Frobenius) of a KITTI rotation
constexpr double kQuaternionTolerance = 1e-3;  // |norm(q) - 1| of a TUM / graph quaternion
constexpr std::uint64_t kMaxExactStamp = std::uint64_t{1} << 53;  // ids exact as double stamps

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

std::vector<std::string_view> split(std::string_view line) {
  std::vector<std::string_view> tokens;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_space(line[i])) ++i;
    const std::size_t start = i;
    while (i < line.size() && !is_space(line[i])) ++i;
    if (i > start) tokens.push_back(line.substr(start, i - start));
  }
  return tokens;
}

std::string format_number(double value) {
  char buffer[64];
  const auto [end, ec] = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return ec == std::errc() ? std::string(buffer, end) : std::string("nan");
}

std::string format_short(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.3g", value);
  return buffer;
}

class LineParser {
 public:
  LineParser(const std::string& name, std::size_t line) : name_(name), line_(line) {}

  [[noreturn]] void fail(const std::string& problem) const {
    throw Error(name_ + ":" + std::to_string(line_) + ": " + problem);
  }

  double number(std::string_view token, const char* what) const {
    std::string_view digits = token;
    // from_chars does not take a leading '+'; accept one (but not "+-1" or "++1").
    if (digits.size() > 1 && digits[0] == '+' && digits[1] != '+' && digits[1] != '-') {
      digits.remove_prefix(1);
    }
    double value = 0.0;
    const auto [ptr, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
    if (ec == std::errc::result_out_of_range && ptr == digits.data() + digits.size()) {
      fail(std::string(what) + " " + quote_bytes(token) + " is out of range");
    }
    if (ec != std::errc() || ptr != digits.data() + digits.size()) {
      fail(std::string("cannot read ") + what + " from " + quote_bytes(token));
    }
    if (!std::isfinite(value)) fail(std::string(what) + " is not finite");
    return value;
  }

  void expect_fields(const std::vector<std::string_view>& tokens, std::size_t count,
                     const char* what) const {
    if (tokens.size() != count) {
      fail(std::string(what) + " needs " + std::to_string(count) + " fields, found " +
           std::to_string(tokens.size()));
    }
  }

  // "tx ty tz qx qy qz qw" starting at tokens[first].
  Eigen::Isometry3d translation_quaternion(const std::vector<std::string_view>& t,
                                           std::size_t first) const {
    const Eigen::Vector3d translation(number(t[first], "tx"), number(t[first + 1], "ty"),
                                      number(t[first + 2], "tz"));
    Eigen::Quaterniond q(number(t[first + 6], "qw"), number(t[first + 3], "qx"),
                         number(t[first + 4], "qy"), number(t[first + 5], "qz"));
    const double norm = q.norm();
    if (!(norm > 0.0)) fail("quaternion is zero");
    if (!(std::abs(norm - 1.0) <= kQuaternionTolerance)) {
      fail("quaternion is not normalized (norm " + format_short(norm) + ", tolerance 1e-3)");
    }
    q.coeffs() /= norm;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = q.toRotationMatrix();
    T.translation() = translation;
    return T;
  }

  Eigen::Isometry3d kitti_pose(const std::vector<std::string_view>& t) const {
    static const char* const kNames[12] = {"R00", "R01", "R02", "tx",  "R10", "R11",
                                           "R12", "ty",  "R20", "R21", "R22", "tz"};
    Eigen::Matrix<double, 3, 4> m;
    for (int k = 0; k < 12; ++k) m(k / 4, k % 4) = number(t[k], kNames[k]);
    const Eigen::Matrix3d R = m.leftCols<3>();
    const double error = (R.transpose() * R - Eigen::Matrix3d::Identity()).norm();
    if (!(error <= kRotationTolerance)) {
      fail("rotation is not orthonormal (|R^T R - I| = " + format_short(error) +
           ", tolerance 1e-3)");
    }
    if (!(R.determinant() > 0.0)) fail("rotation is a reflection (det R < 0)");
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = svd.matrixU() * svd.matrixV().transpose();
    T.translation() = m.col(3);
    return T;
  }

  std::uint64_t graph_id(std::string_view token) const {
    std::uint64_t id = 0;
    const char* first = token.data() + 1;
    const char* last = token.data() + token.size();
    if (token.size() < 2 || token[0] != 'v' || *first < '0' || *first > '9') {
      fail("expected a vertex id 'vN', found " + quote_bytes(token));
    }
    const auto [ptr, ec] = std::from_chars(first, last, id);
    if (ec != std::errc() || ptr != last) {
      fail("cannot read a vertex id (v0 ... v18446744073709551615) from " + quote_bytes(token));
    }
    return id;
  }

 private:
  const std::string& name_;
  std::size_t line_;
};

const char* format_name(TrajectoryFormat format) {
  switch (format) {
    case TrajectoryFormat::kKitti:
      return "KITTI";
    case TrajectoryFormat::kTum:
      return "TUM";
    case TrajectoryFormat::kGraph:
      return "graph";
  }
  return "unknown";
}

}  // namespace

const char* to_string(TrajectoryFormat format) {
  switch (format) {
    case TrajectoryFormat::kKitti:
      return "kitti";
    case TrajectoryFormat::kTum:
      return "tum";
    case TrajectoryFormat::kGraph:
      return "graph";
  }
  return "unknown";
}

TrajectoryFormat parse_trajectory_format(std::string_view name) {
  if (name == "kitti") return TrajectoryFormat::kKitti;
  if (name == "tum") return TrajectoryFormat::kTum;
  if (name == "graph") return TrajectoryFormat::kGraph;
  throw Error("unknown trajectory format " + quote_bytes(name) + " (valid: kitti, tum, graph)");
}

namespace {

Trajectory read_trajectory_lines(LineReader& reader, TrajectoryFormat format) {
  const std::string& name = reader.name();
  Trajectory trajectory;
  std::unordered_map<std::uint64_t, std::size_t> id_line;
  std::size_t previous_stamp_line = 0;
  std::string_view content;
  while (reader.next_line(&content)) {
    const std::size_t line = reader.line_number();
    const auto tokens = split(content);
    if (tokens.empty()) continue;
    if (format == TrajectoryFormat::kTum && tokens[0][0] == '#') continue;
    const LineParser p(name, line);
    switch (format) {
      case TrajectoryFormat::kKitti:
        p.expect_fields(tokens, 12, "KITTI pose (3x4 row-major [R|t])");
        trajectory.poses.push_back(p.kitti_pose(tokens));
        trajectory.stamps.push_back(static_cast<double>(trajectory.stamps.size()));
        break;
      case TrajectoryFormat::kTum: {
        p.expect_fields(tokens, 8, "TUM pose (stamp tx ty tz qx qy qz qw)");
        const double stamp = p.number(tokens[0], "stamp");
        if (!trajectory.stamps.empty() && !(stamp > trajectory.stamps.back())) {
          p.fail("stamp " + format_number(stamp) + " does not increase (line " +
                 std::to_string(previous_stamp_line) + " has " +
                 format_number(trajectory.stamps.back()) + ")");
        }
        trajectory.poses.push_back(p.translation_quaternion(tokens, 1));
        trajectory.stamps.push_back(stamp);
        previous_stamp_line = line;
        break;
      }
      case TrajectoryFormat::kGraph: {
        p.expect_fields(tokens, 8, "graph pose (vN tx ty tz qx qy qz qw)");
        const std::uint64_t id = p.graph_id(tokens[0]);
        const auto [it, inserted] = id_line.emplace(id, line);
        if (!inserted) {
          p.fail("vertex v" + std::to_string(id) + " was already defined on line " +
                 std::to_string(it->second));
        }
        trajectory.poses.push_back(p.translation_quaternion(tokens, 1));
        trajectory.stamps.push_back(static_cast<double>(id));
        trajectory.ids.push_back(id);
        break;
      }
    }
  }
  if (trajectory.poses.empty()) {
    throw Error(name + ": no " + format_name(format) +
                " poses (the file is empty or has only blank or comment lines)");
  }
  return trajectory;
}

}  // namespace

Trajectory parse_trajectory(std::string_view text, TrajectoryFormat format,
                            const std::string& name) {
  MemorySource source(text, name);
  LineReader reader(source);
  return read_trajectory_lines(reader, format);
}

Trajectory read_trajectory(const std::filesystem::path& path, TrajectoryFormat format) {
  InputFile file(path, InputKind::kStreamable);
  LineReader reader(file);
  return read_trajectory_lines(reader, format);
}

std::string format_trajectory(const Trajectory& trajectory, TrajectoryFormat format) {
  const auto fail = [](const std::string& problem) {
    throw Error("cannot format trajectory: " + problem);
  };
  if (trajectory.stamps.size() != trajectory.poses.size()) {
    fail(std::to_string(trajectory.stamps.size()) + " stamps for " +
         std::to_string(trajectory.poses.size()) + " poses");
  }
  const bool has_ids = !trajectory.ids.empty();
  if (has_ids && trajectory.ids.size() != trajectory.poses.size()) {
    fail(std::to_string(trajectory.ids.size()) + " graph ids for " +
         std::to_string(trajectory.poses.size()) + " poses");
  }
  std::string text;
  std::unordered_set<std::uint64_t> ids;
  for (std::size_t k = 0; k < trajectory.poses.size(); ++k) {
    const Eigen::Isometry3d& T = trajectory.poses[k];
    const double stamp = trajectory.stamps[k];
    if (!T.matrix().allFinite()) fail("pose " + std::to_string(k) + " is not finite");
    if (!std::isfinite(stamp)) fail("stamp " + std::to_string(k) + " is not finite");
    const auto put = [&](double value) {
      text += format_number(value);
      text += ' ';
    };
    const auto put_translation_quaternion = [&] {
      Eigen::Quaterniond q(T.linear());
      q.normalize();
      for (double v : {T.translation().x(), T.translation().y(), T.translation().z(), q.x(), q.y(),
                       q.z(), q.w()}) {
        put(v);
      }
    };
    switch (format) {
      case TrajectoryFormat::kKitti:
        for (int r = 0; r < 3; ++r) {
          for (int c = 0; c < 4; ++c) put(T.matrix()(r, c));
        }
        break;
      case TrajectoryFormat::kTum:
        if (k > 0 && !(stamp > trajectory.stamps[k - 1])) {
          fail("TUM stamp " + std::to_string(k) + " (" + format_number(stamp) +
               ") does not increase");
        }
        put(stamp);
        put_translation_quaternion();
        break;
      case TrajectoryFormat::kGraph: {
        if (!has_ids && (!(stamp >= 0.0 && stamp <= static_cast<double>(kMaxExactStamp)) ||
                         stamp != std::floor(stamp))) {
          fail("graph stamp " + std::to_string(k) + " (" + format_number(stamp) +
               ") is not an integer id in [0, 2^53]");
        }
        const std::uint64_t id = has_ids ? trajectory.ids[k] : static_cast<std::uint64_t>(stamp);
        if (!ids.insert(id).second) fail("graph id v" + std::to_string(id) + " is repeated");
        text += 'v' + std::to_string(id) + ' ';
        put_translation_quaternion();
        break;
      }
    }
    text.back() = '\n';
  }
  return text;
}

void write_trajectory(const std::filesystem::path& path, const Trajectory& trajectory,
                      TrajectoryFormat format) {
  std::string text;
  try {
    text = format_trajectory(trajectory, format);
  } catch (const Error& error) {
    throw Error(path.string() + ": " + error.what());
  }
  write_file_atomically(path, [&](std::ostream& out) { out << text; });
}

}  // namespace carat
