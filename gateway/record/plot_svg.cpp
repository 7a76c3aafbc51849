// `oegw replay … --plot FILE.svg`: the page's charts as one static SVG 1.1 document. Each chart is
// a <g class="chart"> whose <title> is its heading; each series a stepped <polyline> (a value
// holds until the next sample, as the FE model holds it) titled with its name and point count;
// each band a <rect> and each marker a <line>, titled with what they show.
#include <algorithm>
#include <cmath>
#include <ctime>

#include <fmt/format.h>

#include "gateway/record/plot.hpp"

namespace oegw::gateway::record {

namespace {

constexpr double kWidth = 1200;
constexpr double kLeft = 110;    // the y axis' labels (node states by name)
constexpr double kLegend = 240;  // the series' names, right of the plot
constexpr double kPlotWidth = kWidth - kLeft - kLegend;
constexpr double kPlotHeight = 130;
constexpr double kChartHeight = kPlotHeight + 60;  // heading above, time labels below

constexpr const char* kPalette[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
                                    "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"};

std::string escaped(std::string_view s) {
  std::string out;
  out.reserve(s.size());
  for (const char c : s) {
    switch (c) {
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '&': out += "&amp;"; break;
      case '"': out += "&quot;"; break;
      default:
        // XML 1.0 allows no control characters but tab, newline and carriage return.
        if (static_cast<unsigned char>(c) >= 0x20 || c == '\t' || c == '\n' || c == '\r') out += c;
    }
  }
  return out;
}

const char* band_fill(std::string_view what) {
  if (what.find(':') != std::string_view::npos) return "rgba(160,0,160,0.15)";  // a sub-device's fault
  if (what == "stale") return "rgba(255,165,0,0.25)";
  if (what == "offline") return "rgba(120,120,120,0.25)";
  return "rgba(220,0,0,0.2)";
}

// The markers drawn on the charts (node and fault markers are in the page's table only).
bool drawn_marker(std::string_view kind) {
  return kind == "emcy" || kind == "emcy_sent" || kind == "command" || kind == "gap" || kind == "run";
}

const char* marker_colour(std::string_view kind) {
  if (kind == "emcy") return "#d00";
  if (kind == "emcy_sent") return "#06c";
  if (kind == "command") return "#080";
  return "#000";  // gap, run
}

// A time of day with milliseconds for `t` seconds after the wall time `t0_us`.
std::string time_of_day(std::int64_t t0_us, double t) {
  const std::int64_t us = t0_us + static_cast<std::int64_t>(std::llround(t * 1e6));
  const std::time_t s = static_cast<std::time_t>(us / 1000000);
  std::tm tm{};
  ::localtime_r(&s, &tm);
  return fmt::format("{:02}:{:02}:{:02}.{:03}", tm.tm_hour, tm.tm_min, tm.tm_sec, (us / 1000) % 1000);
}

struct Axis {
  double end;  // seconds
  double lo, hi;
  double x(double t) const { return kLeft + kPlotWidth * std::clamp(t / end, 0.0, 1.0); }
  double y(double top, double v) const { return top + kPlotHeight * (1.0 - (v - lo) / (hi - lo)); }
};

struct Series {
  std::string name;
  std::vector<std::pair<double, double>> points;
};

// A chart's value axis: its series' lowest to highest value and 5 % more each way.
Axis value_axis(const std::vector<Series>& series, double end) {
  Axis ax{end, INFINITY, -INFINITY};
  for (const Series& s : series)
    for (const auto& [t, v] : s.points) {
      ax.lo = std::min(ax.lo, v);
      ax.hi = std::max(ax.hi, v);
    }
  if (!(ax.lo < ax.hi)) {  // one value (or none): a band around it
    ax.lo = std::isfinite(ax.lo) ? ax.lo - 1 : 0;
    ax.hi = ax.lo + 2;
  }
  const double pad = (ax.hi - ax.lo) * 0.05;
  ax.lo -= pad;
  ax.hi += pad;
  return ax;
}

}  // namespace

struct PlotData::SvgChart {
  std::string heading;
  std::vector<Series> series;
  std::vector<PlacedBand> bands;
  bool node_levels = false;
};

std::vector<PlotData::SvgChart> PlotData::svg_charts(std::size_t max_points) const {
  const auto bands = placed_bands();
  std::vector<SvgChart> charts;
  for (const auto& [fe, fields] : fields_) {
    SvgChart c{fe, {}, {}, false};
    for (const auto& [field, pts] : fields) c.series.push_back(Series{fe + "." + field, drawn(pts, max_points)});
    for (const PlacedBand& b : bands)
      if (b.fe == fe || (b.fe.empty() && (b.on.empty() || std::find(b.on.begin(), b.on.end(), fe) != b.on.end())))
        c.bands.push_back(b);
    charts.push_back(std::move(c));
  }
  if (!nodes_.empty()) {
    SvgChart c{"sub-devices (node state)", {}, {}, true};
    for (const auto& [sub, pts] : nodes_) c.series.push_back(Series{sub, drawn(pts, pts.size() + 1)});
    for (const PlacedBand& b : bands)
      if (b.fe.empty()) c.bands.push_back(b);
    charts.push_back(std::move(c));
  }
  return charts;
}

bool PlotData::write_svg(const std::filesystem::path& out, const std::string& title, std::string& error,
                         std::size_t max_points) const {
  const std::vector<SvgChart> charts = svg_charts(max_points);
  const double end = last_ > 0 ? last_ : 1.0;
  const double height = 50 + kChartHeight * static_cast<double>(charts.size()) + 30;
  std::string svg = fmt::format(
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      "<svg xmlns=\"http://www.w3.org/2000/svg\" version=\"1.1\" width=\"{:.0f}\" height=\"{:.0f}\" "
      "viewBox=\"0 0 {:.0f} {:.0f}\" font-family=\"sans-serif\" font-size=\"11\">\n"
      "<title>{}</title>\n<rect width=\"100%\" height=\"100%\" fill=\"#fff\"/>\n"
      "<text x=\"{:.0f}\" y=\"24\" font-size=\"16\" font-weight=\"bold\">{}</text>\n",
      kWidth, height, kWidth, height, escaped(title), kLeft, escaped(title));
  svg += fmt::format(
      "<text x=\"{:.0f}\" y=\"42\" fill=\"#555\">bands: stale (orange), error / not available (red), offline (grey), "
      "sub-device fault (violet); lines: EMCY received (red), EMCY sent (blue), command (green), run or gap "
      "(black)</text>\n",
      kLeft);
  double top = 50;
  for (const SvgChart& c : charts) {
    svg += svg_chart(c, top, end);
    top += kChartHeight;
  }
  svg += "</svg>\n";

  return write_plot_file(out, svg, error);
}

std::string PlotData::svg_chart(const SvgChart& c, double top, double end) const {
  const Axis ax = c.node_levels ? Axis{end, -1.5, 5.5} : value_axis(c.series, end);
  const double plot_top = top + 22;
  std::string svg;
  svg += fmt::format(
      "<g class=\"chart\">\n<title>{}</title>\n<text x=\"{:.0f}\" y=\"{:.1f}\" font-size=\"13\" "
      "font-weight=\"bold\">{}</text>\n",
      escaped(c.heading), kLeft, top + 14, escaped(c.heading));
  svg += fmt::format(
      "<rect x=\"{:.0f}\" y=\"{:.1f}\" width=\"{:.0f}\" height=\"{:.0f}\" fill=\"none\" "
      "stroke=\"#ccc\"/>\n",
      kLeft, plot_top, kPlotWidth, kPlotHeight);
  for (const PlacedBand& b : c.bands) {
    const double x0 = ax.x(b.from), x1 = ax.x(b.to);
    svg += fmt::format(
        "<rect class=\"band\" x=\"{:.1f}\" y=\"{:.1f}\" width=\"{:.1f}\" height=\"{:.0f}\" "
        "fill=\"{}\"><title>{} {}..{}</title></rect>\n",
        x0, plot_top, std::max(x1 - x0, 1.0), kPlotHeight, band_fill(b.what), escaped(b.what), time_of_day(t0_, b.from),
        time_of_day(t0_, b.to));
  }
  // The y axis: its ends and middle, or the node states by name.
  if (c.node_levels) {
    constexpr const char* kStates[] = {"refused",     "missing",  "idle",       "waiting for boot-up",
                                       "configuring", "starting", "operational"};
    for (int level = -1; level <= 5; ++level)
      svg += fmt::format(
          "<text x=\"{:.0f}\" y=\"{:.1f}\" text-anchor=\"end\" fill=\"#555\" font-size=\"9\">{}"
          "</text>\n",
          kLeft - 4, ax.y(plot_top, level) + 3, kStates[level + 1]);
  } else {
    for (const double v : {ax.lo, (ax.lo + ax.hi) / 2, ax.hi})
      svg += fmt::format("<text x=\"{:.0f}\" y=\"{:.1f}\" text-anchor=\"end\" fill=\"#555\">{:.6g}</text>\n", kLeft - 4,
                         ax.y(plot_top, v) + 4, v);
  }
  for (int i = 0; i <= 5; ++i) {
    const double t = end * i / 5;
    svg += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"middle\" fill=\"#555\">{}</text>\n", ax.x(t),
                       plot_top + kPlotHeight + 14, time_of_day(t0_, t));
  }
  std::size_t colour = 0;
  for (const Series& s : c.series) {
    const char* stroke = kPalette[colour % std::size(kPalette)];
    std::string pts;
    for (std::size_t i = 0; i < s.points.size(); ++i) {
      const double x = ax.x(s.points[i].first), y = ax.y(plot_top, s.points[i].second);
      if (i > 0) pts += fmt::format("{:.1f},{:.1f} ", x, ax.y(plot_top, s.points[i - 1].second));  // the step
      pts += fmt::format("{:.1f},{:.1f} ", x, y);
    }
    svg += fmt::format(
        "<polyline class=\"series\" fill=\"none\" stroke=\"{}\" stroke-width=\"1.5\" points=\"{}\">"
        "<title>{} ({} points)</title></polyline>\n",
        stroke, pts, escaped(s.name), s.points.size());
    const double ly = plot_top + 10 + 14 * static_cast<double>(colour);
    svg += fmt::format(
        "<rect x=\"{:.0f}\" y=\"{:.1f}\" width=\"10\" height=\"3\" fill=\"{}\"/><text x=\"{:.0f}\" "
        "y=\"{:.1f}\">{}</text>\n",
        kLeft + kPlotWidth + 10, ly - 3, stroke, kLeft + kPlotWidth + 24, ly, escaped(s.name));
    ++colour;
  }
  for (const Marker& m : markers_)
    if (drawn_marker(m.kind))
      svg += fmt::format(
          "<line class=\"marker\" x1=\"{0:.1f}\" x2=\"{0:.1f}\" y1=\"{1:.1f}\" y2=\"{2:.1f}\" "
          "stroke=\"{3}\"><title>{4} {5}</title></line>\n",
          ax.x(m.t), plot_top, plot_top + kPlotHeight, marker_colour(m.kind), time_of_day(t0_, m.t), escaped(m.text));
  svg += "</g>\n";
  return svg;
}

}  // namespace oegw::gateway::record
