#include "report_table.hpp"

#include <utility>

#include "carat/base/error.hpp"

namespace carat::cli {
namespace {

/// One Markdown line: "| c1 | c2 | ... |\n".
std::string markdown_line(const std::vector<std::string>& cells) {
  std::string line = "|";
  for (const std::string& cell : cells) line += " " + cell + " |";
  return line + "\n";
}

}  // namespace

ReportTable::ReportTable(std::vector<std::string> headers) : headers_(std::move(headers)) {}

void ReportTable::add_row(std::vector<std::string> cells, nlohmann::json fields) {
  if (cells.size() != headers_.size()) {
    throw Error("report table: a row of " + std::to_string(cells.size()) + " cells under " +
                std::to_string(headers_.size()) + " headers");
  }
  cells_.push_back(std::move(cells));
  rows_.push_back(std::move(fields));
}

std::string ReportTable::markdown() const {
  std::string out = markdown_line(headers_) + "|";
  for (std::size_t k = 0; k < headers_.size(); ++k) out += "---|";
  out += "\n";
  for (const auto& row : cells_) out += markdown_line(row);
  return out;
}

}  // namespace carat::cli
