#pragma once
// Plots as SVG (the reports' and the diagnosis' figures): series of points or lines against one
// variable, horizontal marks, axes with rounded ticks, a legend. No dependency.

#include <string>
#include <vector>

namespace mtcal::services {

struct PlotSeries {
  enum class Style { kPoints, kLine, kDashed };
  std::string name;
  std::string color;  ///< an SVG colour, e.g. "#888" or "steelblue"
  std::vector<double> x, y;
  Style style = Style::kPoints;
};

/// A horizontal line across the plot at y, labelled at its right end (a figure's level).
struct PlotMark {
  double y = 0.0;
  std::string label, color = "#555";
};

struct Plot {
  std::string title, x_label, y_label;
  std::vector<PlotSeries> series;
  std::vector<PlotMark> marks{};
};

/// Text for XML and HTML content and attributes (& < > " escaped).
std::string xmlEscape(const std::string& text);

/// The plot as an SVG document (800 x 420 px, scalable: it has a viewBox). Non-finite points
/// are left out; a line breaks at them.
std::string plotSvg(const Plot& plot);

}  // namespace mtcal::services
