#pragma once

// A report table kept two ways: as Markdown (the text of a report) and as a JSON array (its
// machine-readable twin). Cells hold the text the Markdown shows; each row's JSON object holds
// the numbers themselves under their own keys.

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace carat::cli {

/// Rows of one table, as Markdown cells and as JSON objects.
class ReportTable {
 public:
  /// A table with these column headers.
  explicit ReportTable(std::vector<std::string> headers);

  /// Adds a row: one Markdown cell per header, and the row's JSON object. Throws carat::Error
  /// when the cells do not match the headers in number.
  void add_row(std::vector<std::string> cells, nlohmann::json fields);

  /// The table in Markdown: "| a | b |", "|---|---|", then one such line per row, each line
  /// ending in a newline.
  std::string markdown() const;

  /// The rows' JSON objects, in order, as one array.
  const nlohmann::json& json() const { return rows_; }

 private:
  std::vector<std::string> headers_;
  std::vector<std::vector<std::string>> cells_;
  nlohmann::json rows_ = nlohmann::json::array();
};

}  // namespace carat::cli
