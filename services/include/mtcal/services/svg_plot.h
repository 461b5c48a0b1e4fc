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
  bool equal_scale = false;  ///< one unit of x as long as one of y (maps, where shapes and directions matter)
};

/// A polar plot of radial deviations around a nominal circle, magnified: the ballbar's
/// picture. Each series is a path of (angle rad, deviation) points.
struct PolarSeries {
  std::string name, color;
  std::vector<double> angle_rad, deviation;
};
struct PolarPlot {
  std::string title, unit;                          ///< the deviations' unit
  std::string first_axis = "X", second_axis = "Y";  ///< the plane's axes: 0 rad along the first
  std::vector<PolarSeries> series;
};
/// 560 x 560 px: the nominal circle, rings every scale step, the deviations magnified so that
/// the largest reaches a third of the radius (the scale printed); at most 3600 points drawn a
/// path (every n-th), its `data-points` the series' size.
std::string polarPlotSvg(const PolarPlot& plot);

/// Text for XML and HTML content and attributes (& < > " escaped).
std::string xmlEscape(const std::string& text);

/// The plot as an SVG document (800 px wide, 420 px high and the legend's rows below; scalable:
/// it has a viewBox). Non-finite points
/// are left out; a line breaks at them. Each point carries its values as a title (shown on
/// hover).
std::string plotSvg(const Plot& plot);

}  // namespace mtcal::services
