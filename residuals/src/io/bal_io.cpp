#include "carat/residuals/io/bal_io.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "carat/base/atomic_file.hpp"
#include "carat/base/error.hpp"
#include "carat/base/input_file.hpp"

namespace carat {
namespace {

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

/// Whitespace-separated tokens of a LineReader, with the line of the last one for messages.
class BalTokens {
 public:
  explicit BalTokens(LineReader& reader) : reader_(reader) {}

  /// The next token; false at the end of the input.
  bool next(std::string_view* token) {
    if (!at_token()) return false;
    const std::size_t start = position_;
    while (position_ < line_.size() && !is_space(line_[position_])) ++position_;
    *token = line_.substr(start, position_ - start);
    return true;
  }

  /// The next token, or an error naming what the file ended in.
  /// `describe()` names what is being read; it is called only to build the message.
  template <typename Describe>
  std::string_view expect(const Describe& describe) {
    std::string_view token;
    if (!next(&token)) fail("the file ends in " + describe() + " (truncated?)");
    return token;
  }

  [[noreturn]] void fail(const std::string& problem) const {
    throw Error(reader_.name() + ":" + std::to_string(std::max<std::size_t>(1, line())) + ": " +
                problem);
  }

  /// The line of the last token (or the last line read).
  std::size_t line() const { return reader_.line_number(); }

  /// Bytes not yet tokenized when the input knows its size.
  std::optional<std::uint64_t> remaining() const {
    const auto rest = reader_.remaining();
    if (!rest) return std::nullopt;
    return *rest + (line_.size() - position_);
  }

  /// A header count: an integer in [1, 2^31 - 1].
  int count(std::string_view token, const char* what) const {
    std::int64_t value = 0;
    const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
    if (ec != std::errc() || end != token.data() + token.size() || value < 1 ||
        value > std::numeric_limits<int>::max()) {
      fail(std::string("header: ") + what + " must be an integer in [1, 2147483647], found " +
           quote_bytes(token));
    }
    return static_cast<int>(value);
  }

  /// The next token as an index in [0, count); `where()` names what is being read.
  template <typename Where>
  int next_index(const Where& where, const char* what, int count) {
    std::int64_t value = 0;
    if (parse_whole(&value, [count](std::int64_t v) { return v >= 0 && v < count; })) {
      return static_cast<int>(value);
    }
    return index(expect(where), what, count);  // the same token again, for its message
  }

  /// The next token as a finite number; `where()` names what is being read, `describe()` the
  /// number.
  template <typename Where, typename Describe>
  double next_number(const Where& where, const Describe& describe) {
    double value = 0.0;
    if (parse_whole(&value, [](double v) { return std::isfinite(v); })) return value;
    return number(expect(where), describe);  // the same token again, for its message
  }

  /// An index in [0, count).
  int index(std::string_view token, const char* what, int count) const {
    std::int64_t value = 0;
    const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
    if (ec != std::errc() || end != token.data() + token.size()) {
      fail(std::string("cannot read a ") + what + " index from " + quote_bytes(token));
    }
    if (value < 0 || value >= count) {
      fail(std::string(what) + " index " + std::to_string(value) + " is out of range [0, " +
           std::to_string(count) + ")");
    }
    return static_cast<int>(value);
  }

  /// A finite number.
  /// A finite number; `describe()` names it for messages.
  template <typename Describe>
  double number(std::string_view token, const Describe& describe) const {
    double value = 0.0;
    const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
    if (ec == std::errc() && end == token.data() + token.size() && std::isfinite(value)) {
      return value;
    }
    if (end != token.data() + token.size() ||
        (ec != std::errc() && ec != std::errc::result_out_of_range)) {
      fail("cannot read " + describe() + " from " + quote_bytes(token));
    }
    if (ec == std::errc::result_out_of_range) {
      fail(describe() + " " + quote_bytes(token) + " is out of range");
    }
    fail(describe() + " " + quote_bytes(token) + " is not finite");
  }

 private:
  /// Moves to the start of the next token; false at the end of the input.
  bool at_token() {
    for (;;) {
      while (position_ < line_.size() && is_space(line_[position_])) ++position_;
      if (position_ < line_.size()) return true;
      if (!reader_.next_line(&line_)) return false;
      position_ = 0;
    }
  }

  /// Reads the next token into `value` and moves past it when std::from_chars reads the whole
  /// token and `accept(*value)` holds; otherwise leaves the position at the token's start (or the
  /// end of the input).
  template <typename T, typename Accept>
  bool parse_whole(T* value, const Accept& accept) {
    if (!at_token()) return false;
    const char* first = line_.data() + position_;
    const char* last = line_.data() + line_.size();
    const auto [end, ec] = std::from_chars(first, last, *value);
    if (ec != std::errc() || (end != last && !is_space(*end)) || !accept(*value)) {
      return false;
    }
    position_ += static_cast<std::size_t>(end - first);
    return true;
  }

  LineReader& reader_;
  std::string_view line_;
  std::size_t position_ = 0;
};

/// Which of `count` indices the observations use, asked for in increasing order. With the input's
/// size known, the counts are bounded by it and a flag per index is kept; from a stream of unknown
/// size the used indices are kept sorted instead, so that memory follows the data, not the header.
class IndexUse {
 public:
  IndexUse(int count, bool bounded) {
    if (bounded) flags_.assign(static_cast<std::size_t>(count), 0);
  }
  void add(int index) {
    if (!flags_.empty()) {
      flags_[static_cast<std::size_t>(index)] = 1;
    } else {
      sorted_.push_back(index);
    }
  }
  /// Call once after the last add().
  void finish() {
    std::sort(sorted_.begin(), sorted_.end());
    sorted_.erase(std::unique(sorted_.begin(), sorted_.end()), sorted_.end());
  }
  /// Whether `index` is used; indices must be asked for in increasing order.
  bool used(int index) {
    if (!flags_.empty()) return flags_[static_cast<std::size_t>(index)] != 0;
    while (next_ < sorted_.size() && sorted_[next_] < index) ++next_;
    return next_ < sorted_.size() && sorted_[next_] == index;
  }

 private:
  std::vector<char> flags_;
  std::vector<int> sorted_;
  std::size_t next_ = 0;
};

BalProblem read_bal_tokens(BalTokens& tokens) {
  const auto header = [] { return std::string("the header"); };
  const int num_cameras = tokens.count(tokens.expect(header), "num_cameras");
  const int num_points = tokens.count(tokens.expect(header), "num_points");
  const int num_observations = tokens.count(tokens.expect(header), "num_observations");

  // Each number takes at least one byte and one separator: refuse counts the input cannot hold
  // before allocating for them.
  const std::uint64_t numbers = 4 * static_cast<std::uint64_t>(num_observations) +
                                9 * static_cast<std::uint64_t>(num_cameras) +
                                3 * static_cast<std::uint64_t>(num_points);
  const auto remaining = tokens.remaining();
  if (remaining && *remaining + 1 < 2 * numbers) {
    tokens.fail("header: " + std::to_string(num_cameras) + " cameras, " +
                std::to_string(num_points) + " points and " + std::to_string(num_observations) +
                " observations need " + std::to_string(numbers) + " numbers (at least " +
                std::to_string(2 * numbers - 1) + " bytes), but only " +
                std::to_string(*remaining) + " bytes follow: the file is truncated");
  }
  // A stream of unknown size grows the arrays as it delivers the data.
  const auto reserve = [&](auto& v, int n) {
    v.reserve(remaining ? static_cast<std::size_t>(n)
                        : std::min<std::size_t>(static_cast<std::size_t>(n), 1u << 16));
  };

  BalProblem problem;
  reserve(problem.observations, num_observations);
  IndexUse camera_use(num_cameras, remaining.has_value());
  IndexUse point_use(num_points, remaining.has_value());
  for (int k = 0; k < num_observations; ++k) {
    const auto where = [&] {
      return "observation " + std::to_string(k) + " of " + std::to_string(num_observations);
    };
    BalObservation o;
    o.camera = tokens.next_index(where, "camera", num_cameras);
    o.point = tokens.next_index(where, "point", num_points);
    o.x = tokens.next_number(where, [] { return std::string("observation x"); });
    o.y = tokens.next_number(where, [] { return std::string("observation y"); });
    camera_use.add(o.camera);
    point_use.add(o.point);
    problem.observations.push_back(o);
  }

  camera_use.finish();
  point_use.finish();
  reserve(problem.cameras, num_cameras);
  for (int i = 0; i < num_cameras; ++i) {
    BalCamera camera;
    for (int k = 0; k < 9; ++k) {
      const auto where = [&] {
        return "camera " + std::to_string(i) + " (parameter " + std::to_string(k + 1) +
               " of 9; the header promises " + std::to_string(num_cameras) + " cameras)";
      };
      camera[k] = tokens.next_number(
          where, [&] { return "camera " + std::to_string(i) + " parameter " + std::to_string(k); });
      if (k == 0 && !camera_use.used(i)) {
        tokens.fail("camera " + std::to_string(i) +
                    " observes no point (every camera and point must take part in an "
                    "observation)");
      }
    }
    problem.cameras.push_back(camera);
  }

  reserve(problem.points, num_points);
  for (int i = 0; i < num_points; ++i) {
    Eigen::Vector3d point;
    for (int k = 0; k < 3; ++k) {
      const auto where = [&] {
        return "point " + std::to_string(i) + " (coordinate " + std::to_string(k + 1) +
               " of 3; the header promises " + std::to_string(num_points) + " points)";
      };
      point[k] = tokens.next_number(
          where, [&] { return "point " + std::to_string(i) + " coordinate " + std::to_string(k); });
      if (k == 0 && !point_use.used(i)) {
        tokens.fail("point " + std::to_string(i) +
                    " is observed by no camera (every camera and point must take part in an "
                    "observation)");
      }
    }
    problem.points.push_back(point);
  }

  std::string_view extra;
  if (tokens.next(&extra)) {
    tokens.fail("unexpected data " + quote_bytes(extra) +
                " after the last point (the header "
                "promises " +
                std::to_string(num_points) + " points)");
  }
  return problem;
}

BalProblem read_bal_source(ByteSource& source) {
  LineReader reader(source);
  BalTokens tokens(reader);
  return read_bal_tokens(tokens);
}

void append_number(std::string& out, double value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  out.append(buffer, result.ptr);
}

}  // namespace

BalProblem read_bal(const std::filesystem::path& path) {
  InputFile file(path, InputKind::kStreamable);
  return read_bal_source(file);
}

BalProblem parse_bal(std::string_view text, const std::string& name) {
  MemorySource source(text, name);
  return read_bal_source(source);
}

void write_bal(std::ostream& out, const BalProblem& problem) {
  check_bal_problem(problem, "write_bal");
  std::string text;
  text.reserve(1 << 16);
  const auto flush = [&](bool force) {
    if (force || text.size() > (1u << 16) - 256) {
      out.write(text.data(), static_cast<std::streamsize>(text.size()));
      text.clear();
    }
  };
  text += std::to_string(problem.cameras.size()) + " " + std::to_string(problem.points.size()) +
          " " + std::to_string(problem.observations.size()) + "\n";
  for (const BalObservation& o : problem.observations) {
    text += std::to_string(o.camera);
    text += ' ';
    text += std::to_string(o.point);
    text += ' ';
    append_number(text, o.x);
    text += ' ';
    append_number(text, o.y);
    text += '\n';
    flush(false);
  }
  for (const BalCamera& camera : problem.cameras) {
    for (int k = 0; k < 9; ++k) {
      append_number(text, camera[k]);
      text += '\n';
    }
    flush(false);
  }
  for (const Eigen::Vector3d& point : problem.points) {
    for (int k = 0; k < 3; ++k) {
      append_number(text, point[k]);
      text += '\n';
    }
    flush(false);
  }
  flush(true);
}

void write_bal(const std::filesystem::path& path, const BalProblem& problem) {
  check_bal_problem(problem, "write_bal");
  write_file_atomically(path, [&](std::ostream& out) { write_bal(out, problem); });
}

}  // namespace carat
