#include "mtcal/services/svg_plot.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace mtcal::services {
namespace {

constexpr double kWidth = 800, kHeight = 420, kLeft = 70, kRight = 20, kTop = 40, kBottom = 60;

/// A tick step of 1, 2 or 5 times a power of ten giving about `count` ticks over the span.
double tickStep(double span, int count) {
  if (!(span > 0.0)) return 1.0;
  const double raw = span / count;
  const double power = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * power >= raw) return m * power;
  }
  return 10.0 * power;
}

}  // namespace

std::string xmlEscape(const std::string& text) {
  std::string out;
  for (const char c : text) {
    switch (c) {
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '&':
        out += "&amp;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string plotSvg(const Plot& plot) {
  double x0 = std::numeric_limits<double>::infinity(), x1 = -x0, y0 = x0, y1 = -x0;
  for (const auto& s : plot.series) {
    for (std::size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      x0 = std::min(x0, s.x[i]);
      x1 = std::max(x1, s.x[i]);
      y0 = std::min(y0, s.y[i]);
      y1 = std::max(y1, s.y[i]);
    }
  }
  for (const auto& m : plot.marks) {
    if (std::isfinite(m.y) && std::isfinite(y0)) y0 = std::min(y0, m.y), y1 = std::max(y1, m.y);
  }
  if (!std::isfinite(x0)) x0 = 0, x1 = 1, y0 = 0, y1 = 1;
  if (x1 - x0 <= 0.0) x0 -= 0.5, x1 += 0.5;
  if (y1 - y0 <= 0.0) y0 -= 0.5, y1 += 0.5;
  const double pad = 0.05 * (y1 - y0);
  y0 -= pad;
  y1 += pad;
  const double w = kWidth - kLeft - kRight, h = kHeight - kTop - kBottom;
  if (plot.equal_scale) {
    // One unit as long across as up: the narrower range widened about its middle.
    const double per_pixel = std::max((x1 - x0) / w, (y1 - y0) / h);
    const double xm = 0.5 * (x0 + x1), ym = 0.5 * (y0 + y1);
    x0 = xm - 0.5 * per_pixel * w, x1 = xm + 0.5 * per_pixel * w;
    y0 = ym - 0.5 * per_pixel * h, y1 = ym + 0.5 * per_pixel * h;
  }
  // The legend in rows below the plot, as many as its entries need: it covers no data.
  std::vector<std::pair<double, double>> legend_at;  // x, baseline y of each series' entry
  double legend_x = kLeft, legend_y = kHeight + 2;
  for (const auto& s : plot.series) {
    const double width = 22 + 7.0 * static_cast<double>(s.name.size());
    if (legend_x > kLeft && legend_x + width > kWidth - kRight) legend_x = kLeft, legend_y += 18;
    legend_at.emplace_back(legend_x + 10, legend_y);
    legend_x += width;
  }
  const double height = plot.series.empty() ? kHeight : legend_y + 10;
  auto px = [&](double x) { return kLeft + (x - x0) / (x1 - x0) * w; };
  auto py = [&](double y) { return kTop + (y1 - y) / (y1 - y0) * h; };
  std::string svg = fmt::format(
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{0}\" height=\"{1}\" viewBox=\"0 0 {0} {1}\" "
      "font-family=\"sans-serif\" font-size=\"12\">\n"
      "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
      "<text x=\"{2}\" y=\"22\" font-size=\"15\">{3}</text>\n"
      "<rect x=\"{2}\" y=\"{4}\" width=\"{5}\" height=\"{6}\" fill=\"none\" stroke=\"#444\"/>\n",
      kWidth, height, kLeft, xmlEscape(plot.title), kTop, w, h);
  const double xs = tickStep(x1 - x0, 8), ys = tickStep(y1 - y0, 6);
  for (double t = std::ceil(x0 / xs) * xs; t <= x1 + 1e-9 * xs; t += xs) {
    svg += fmt::format(
        "<line x1=\"{0:.1f}\" y1=\"{1}\" x2=\"{0:.1f}\" y2=\"{2}\" stroke=\"#ddd\"/>"
        "<text x=\"{0:.1f}\" y=\"{3}\" text-anchor=\"middle\">{4:g}</text>\n",
        px(t), kTop, kTop + h, kTop + h + 16, std::abs(t) < 1e-12 * xs ? 0.0 : t);
  }
  for (double t = std::ceil(y0 / ys) * ys; t <= y1 + 1e-9 * ys; t += ys) {
    svg += fmt::format(
        "<line x1=\"{1}\" y1=\"{0:.1f}\" x2=\"{2}\" y2=\"{0:.1f}\" stroke=\"#ddd\"/>"
        "<text x=\"{3}\" y=\"{4:.1f}\" text-anchor=\"end\">{5:g}</text>\n",
        py(t), kLeft, kLeft + w, kLeft - 6, py(t) + 4, std::abs(t) < 1e-12 * ys ? 0.0 : t);
  }
  if (y0 < 0.0 && y1 > 0.0) {
    svg += fmt::format("<line x1=\"{}\" y1=\"{:.1f}\" x2=\"{}\" y2=\"{:.1f}\" stroke=\"#888\"/>\n", kLeft, py(0.0),
                       kLeft + w, py(0.0));
  }
  svg += fmt::format("<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text>\n", kLeft + w / 2, kHeight - 18,
                     xmlEscape(plot.x_label));
  svg += fmt::format("<text x=\"16\" y=\"{0}\" text-anchor=\"middle\" transform=\"rotate(-90 16 {0})\">{1}</text>\n",
                     kTop + h / 2, xmlEscape(plot.y_label));
  for (const auto& m : plot.marks) {
    if (!std::isfinite(m.y)) continue;
    svg += fmt::format(
        "<line x1=\"{0}\" y1=\"{1:.1f}\" x2=\"{2}\" y2=\"{1:.1f}\" stroke=\"{3}\" stroke-dasharray=\"2 3\"/>"
        "<text x=\"{4}\" y=\"{5:.1f}\" text-anchor=\"end\" fill=\"{3}\">{6}</text>\n",
        kLeft, py(m.y), kLeft + w, m.color, kLeft + w - 4, py(m.y) - 3, xmlEscape(m.label));
  }
  const std::string x_name = xmlEscape(plot.x_label), y_name = xmlEscape(plot.y_label);
  for (std::size_t k = 0; k < plot.series.size(); ++k) {
    const auto& s = plot.series[k];
    const auto [lx, ly] = legend_at[k];
    const auto finite = [&](std::size_t i) { return std::isfinite(s.x[i]) && std::isfinite(s.y[i]); };
    if (s.style == PlotSeries::Style::kPoints) {
      svg += fmt::format("<g class=\"series\" data-name=\"{}\" fill=\"{}\" fill-opacity=\"0.7\">", xmlEscape(s.name),
                         s.color);
      for (std::size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
        if (!finite(i)) continue;
        // The values on hover (a browser shows an element's title).
        svg += fmt::format("<circle cx=\"{:.1f}\" cy=\"{:.1f}\" r=\"2\"><title>{}, {} {:g}: {} {:.4g}</title></circle>",
                           px(s.x[i]), py(s.y[i]), xmlEscape(s.name), x_name, s.x[i], y_name, s.y[i]);
      }
      svg += "</g>\n";
      svg += fmt::format("<circle cx=\"{:.1f}\" cy=\"{:.1f}\" r=\"4\" fill=\"{}\"/>", lx, ly - 4, s.color);
    } else {
      const char* dash = s.style == PlotSeries::Style::kDashed ? " stroke-dasharray=\"6 4\"" : "";
      std::string d;
      bool pen_down = false;
      for (std::size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
        if (!finite(i)) {
          pen_down = false;
          continue;
        }
        d += fmt::format("{}{:.1f},{:.1f} ", pen_down ? "L" : "M", px(s.x[i]), py(s.y[i]));
        pen_down = true;
      }
      svg += fmt::format("<path class=\"series\" data-name=\"{}\" d=\"{}\" fill=\"none\" stroke=\"{}\"{}/>\n",
                         xmlEscape(s.name), d, s.color, dash);
      svg += fmt::format("<line x1=\"{:.1f}\" y1=\"{:.1f}\" x2=\"{:.1f}\" y2=\"{:.1f}\" stroke=\"{}\"{}/>", lx - 6,
                         ly - 4, lx + 4, ly - 4, s.color, dash);
    }
    svg += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\">{}</text>\n", lx + 8, ly, xmlEscape(s.name));
  }
  svg += "</svg>\n";
  return svg;
}

std::string polarPlotSvg(const PolarPlot& plot) {
  constexpr double kSize = 560, kCentre = kSize / 2, kNominal = 170, kBand = 80;  // px
  double largest = 0.0;
  for (const auto& s : plot.series)
    for (const double d : s.deviation)
      if (std::isfinite(d)) largest = std::max(largest, std::abs(d));
  // The ring spacing: a rounded step so that about 2 rings lie each side of the nominal circle.
  const double step = tickStep(std::max(largest, 1e-9), 2);
  const double rings = std::max(1.0, std::ceil(largest / step));
  const double px_per_unit = kBand / (rings * step);
  std::string svg = fmt::format(
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{0}\" height=\"{0}\" viewBox=\"0 0 {0} {0}\" "
      "font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
      "<text x=\"12\" y=\"22\" font-size=\"15\">{1}</text>\n",
      kSize, xmlEscape(plot.title));
  for (double k = -rings; k <= rings + 1e-9; k += 1.0) {
    svg += fmt::format("<circle cx=\"{0}\" cy=\"{0}\" r=\"{1:.1f}\" fill=\"none\" stroke=\"{2}\"/>\n", kCentre,
                       kNominal + k * step * px_per_unit, k == 0.0 ? "#444" : "#ddd");
  }
  svg += fmt::format(
      "<line x1=\"{0}\" y1=\"{1}\" x2=\"{2}\" y2=\"{1}\" stroke=\"#bbb\"/><line x1=\"{1}\" y1=\"{0}\" x2=\"{1}\" "
      "y2=\"{2}\" stroke=\"#bbb\"/>\n<text x=\"{3}\" y=\"{4}\">+{5}</text><text x=\"{6}\" y=\"{7}\">+{8}</text>\n",
      kCentre - kNominal - kBand - 10, kCentre, kCentre + kNominal + kBand + 10, kCentre + kNominal + kBand + 2,
      kCentre - 4, xmlEscape(plot.first_axis), kCentre + 4, kCentre - kNominal - kBand - 2,
      xmlEscape(plot.second_axis));
  svg += fmt::format("<text x=\"12\" y=\"{}\">rings every {:g} {} (outward +)</text>\n", kSize - 12, step,
                     xmlEscape(plot.unit));
  double legend_y = 44;
  for (const auto& s : plot.series) {
    std::string d;
    // At most 3600 points a path (0.1 degree on a full circle): a 50 kHz capture would make a
    // document of megabytes the eye cannot tell from this.
    const std::size_t stride = std::max<std::size_t>(1, (s.deviation.size() + 3599) / 3600);
    for (std::size_t i = 0; i < s.angle_rad.size() && i < s.deviation.size(); i += stride) {
      if (!std::isfinite(s.angle_rad[i]) || !std::isfinite(s.deviation[i])) continue;
      const double r = kNominal + s.deviation[i] * px_per_unit;
      d += fmt::format("{}{:.1f},{:.1f} ", d.empty() ? "M" : "L", kCentre + r * std::cos(s.angle_rad[i]),
                       kCentre - r * std::sin(s.angle_rad[i]));
    }
    svg += fmt::format(
        "<path class=\"series\" data-name=\"{}\" data-points=\"{}\" d=\"{}\" fill=\"none\" "
        "stroke=\"{}\"/>\n",
        xmlEscape(s.name), s.deviation.size(), d, s.color);
    svg += fmt::format(
        "<line x1=\"12\" y1=\"{0}\" x2=\"28\" y2=\"{0}\" stroke=\"{1}\"/><text x=\"34\" "
        "y=\"{2}\">{3}</text>\n",
        legend_y, s.color, legend_y + 4, xmlEscape(s.name));
    legend_y += 16;
  }
  return svg + "</svg>\n";
}

}  // namespace mtcal::services
