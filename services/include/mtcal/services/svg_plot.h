#pragma once
// Scatter plots as standalone SVG files (the diagnosis report's figures): points of one or
// more series against one variable, axes with rounded ticks, a legend. No dependency.

#include <string>
#include <vector>

namespace mtcal::services {

struct PlotSeries {
  std::string name;
  std::string color;  ///< an SVG colour, e.g. "#888" or "steelblue"
  std::vector<double> x, y;
};

struct Plot {
  std::string title, x_label, y_label;
  std::vector<PlotSeries> series;
};

/// The plot as an SVG document (800 x 420 px). Non-finite points are left out.
std::string plotSvg(const Plot& plot);

}  // namespace mtcal::services
