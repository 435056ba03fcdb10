#include "svg_document.hpp"

#include <sstream>

#include "carat/base/atomic_file.hpp"

namespace carat::cli {

std::string svg_escape(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '<')
      out += "&lt;";
    else if (c == '>')
      out += "&gt;";
    else if (c == '&')
      out += "&amp;";
    else
      out += c;
  }
  return out;
}

std::string svg_header(const std::string& title) {
  std::ostringstream s;
  s << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << kSvgWidth << "\" height=\""
    << kSvgHeight << "\" viewBox=\"0 0 " << kSvgWidth << ' ' << kSvgHeight
    << "\" font-family=\"sans-serif\">\n"
    << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
    << "<text x=\"" << kSvgWidth / 2 << "\" y=\"28\" text-anchor=\"middle\" font-size=\"18\">"
    << svg_escape(title) << "</text>\n";
  return s.str();
}

const char* palette_colour(std::size_t k) {
  static const char* const kColours[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728",
                                         "#9467bd", "#8c564b", "#e377c2", "#17becf"};
  return kColours[k % 8];
}

void write_svg(const std::filesystem::path& path, const std::string& svg) {
  write_file_atomically(path, [&](std::ostream& out) { out << svg; });
}

}  // namespace carat::cli
