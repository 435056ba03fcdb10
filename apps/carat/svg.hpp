#pragma once

// Every SVG picture of the tool: the shared canvas and writer, top views in metres, and charts.

#include "svg_charts.hpp"
#include "svg_document.hpp"
#include "svg_top_view.hpp"
