#pragma once

// The pieces every SVG picture of the tool shares: the canvas, text escaping, the palette and
// writing a document to a file.

#include <cstddef>
#include <filesystem>
#include <string>

namespace carat::cli {

inline constexpr double kSvgWidth = 800.0;        ///< canvas width of a picture (pixels)
inline constexpr double kSvgHeight = 640.0;       ///< canvas height of a picture (pixels)
inline constexpr double kSvgMargin = 50.0;        ///< blank border around the drawing (pixels)
inline constexpr double kSvgLegendWidth = 180.0;  ///< column right of the drawing for the legend

/// `text` with `<`, `>` and `&` escaped for an SVG text node or attribute.
std::string svg_escape(const std::string& text);

/// The opening of a kSvgWidth x kSvgHeight document: white background and `title` centred on top.
std::string svg_header(const std::string& title);

/// The k-th colour of the eight-colour categorical palette (cycles), as "#rrggbb".
const char* palette_colour(std::size_t k);

/// Writes `svg` to `path` atomically (complete or untouched).
void write_svg(const std::filesystem::path& path, const std::string& svg);

}  // namespace carat::cli
