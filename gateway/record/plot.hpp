// `oegw replay … --plot FILE.html|FILE.svg` (docs/guides/black-box.md#pictures): the
// replayed timeline — each FE's fields over time with its fault and stale bands, EMCY markers,
// the sub-devices' node states, the commands. The page is drawn by Chart.js 3.9 (Debian's
// libjs-chart.js), whose script is put into the page itself: it opens without a network and
// without the package on the viewing machine. The SVG is the same picture as a static document
// for a report (no script: it is written here, element by element, with each series, band and
// marker named in a <title> so that a viewer, a test or a search finds them).
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <string_view>
#include <vector>

namespace oegw::gateway::record {

// Where Debian's libjs-chart.js puts its script.
inline constexpr std::string_view kChartJs = "/usr/share/javascript/chart.js/chart.min.js";

class PlotData {
 public:
  // A new run of the recording (its name is shown; the time axis goes on).
  void begin_run(const std::string& name);
  // Sub-device `subdevice` feeds FE `fe` ("joystick.1"): its fault bands are drawn on that FE's
  // chart (and on the sub-devices' chart). Without it, on every chart.
  void feeds(const std::string& subdevice, const std::string& fe) { feeds_[subdevice].insert(fe); }
  // One timeline line (an event or decision of the .events format) at a wall time (µs).
  void add(std::int64_t wall_us, std::string_view text);

  // The page; false and `error` when the script or the file cannot be read or written.
  // `max_points`: each field's series thinned to about this many points (the first, smallest,
  // largest and last value of each time slice), so that hours of recording stay viewable.
  bool write_html(const std::filesystem::path& out, const std::string& title, std::string& error,
                  const std::filesystem::path& chart_js = std::filesystem::path(kChartJs),
                  std::size_t max_points = 4000) const;

  // The same charts as one static SVG document (`max_points` as above).
  bool write_svg(const std::filesystem::path& out, const std::string& title, std::string& error,
                 std::size_t max_points = 2000) const;

  // For the tests: the series' names ("joystick.1.x"), bands and markers collected.
  [[nodiscard]] std::vector<std::string> series_names() const;
  [[nodiscard]] std::size_t bands() const { return bands_.size(); }
  [[nodiscard]] std::size_t markers() const { return markers_.size(); }

 private:
  struct Point {
    double t;  // seconds since the first line
    double v;
  };
  struct Band {             // an FE not valid, or a sub-device faulty, from..to
    std::string fe;         // the FE chart it belongs to ("" for a sub-device fault: on every FE it feeds)
    std::string subdevice;  // a sub-device fault's
    std::string what;
    double from, to;
  };
  struct Marker {
    double t;
    std::string kind;  // "emcy", "emcy_sent", "command", "run", "gap"
    std::string text;
  };
  // A band as drawn: closed ones and those still open at the end; a sub-device's fault band on
  // the FEs it feeds (`on`; empty: every FE).
  struct PlacedBand {
    std::string fe;
    std::vector<std::string> on;
    std::string what;
    double from, to;
  };
  [[nodiscard]] std::vector<PlacedBand> placed_bands() const;
  // Each field's points held to the end and thinned.
  [[nodiscard]] std::vector<std::pair<double, double>> drawn(const std::vector<Point>& pts,
                                                             std::size_t max_points) const;
  // write_html's data: the series, bands, nodes and markers as JSON, safe inside a script element.
  [[nodiscard]] std::string html_data(const std::string& title, std::size_t max_points) const;
  // write_svg's charts (one per FE, then the sub-devices') and the drawing of one at `top`.
  struct SvgChart;
  [[nodiscard]] std::vector<SvgChart> svg_charts(std::size_t max_points) const;
  [[nodiscard]] std::string svg_chart(const SvgChart& c, double top, double end) const;
  [[nodiscard]] double seconds(std::int64_t wall_us);
  void close_band(std::map<std::string, std::pair<std::string, double>>& open, const std::string& key, double t,
                  const std::string& fe);

  std::string pending_run_;  // shown at the next line
  std::int64_t t0_ = -1;
  double last_ = 0;
  std::map<std::string, std::map<std::string, std::vector<Point>>> fields_;  // FE -> field -> points
  std::map<std::string, std::vector<Point>> nodes_;                          // sub-device -> state level
  std::map<std::string, std::pair<std::string, double>> fe_status_open_;     // FE -> (status, since)
  std::map<std::string, std::pair<std::string, double>> fault_open_;         // sub-device -> (reason, since)
  std::vector<Band> bands_;
  std::map<std::string, std::set<std::string>> feeds_;  // sub-device -> the FEs it feeds
  std::vector<Marker> markers_;
};

// Writes a drawn plot (the page or the picture) to `out`; false and `error` naming the file when
// it cannot be opened or written.
bool write_plot_file(const std::filesystem::path& out, std::string_view text, std::string& error);

// A node state as a level of the sub-devices' chart (operational highest, refused lowest).
[[nodiscard]] int node_level(std::string_view state);

}  // namespace oegw::gateway::record
