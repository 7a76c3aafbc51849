#include "gateway/record/plot.hpp"

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "gateway/record/replay.hpp"

namespace oegw::gateway::record {

namespace {

std::vector<std::string_view> split(std::string_view s) {
  std::vector<std::string_view> out;
  std::size_t at = 0;
  while (at <= s.size()) {
    const auto sp = s.find(' ', at);
    out.push_back(s.substr(at, sp == std::string_view::npos ? std::string_view::npos : sp - at));
    if (sp == std::string_view::npos) break;
    at = sp + 1;
  }
  return out;
}

// The first, smallest, largest and last point of each of `n` slices of time.
std::vector<std::pair<double, double>> thin(const std::vector<std::pair<double, double>>& pts, std::size_t n) {
  if (pts.size() <= n || n < 8) return pts;
  const double t0 = pts.front().first, t1 = pts.back().first;
  const std::size_t slices = n / 4;
  const double w = (t1 - t0) / static_cast<double>(slices) + 1e-12;
  std::vector<std::pair<double, double>> out;
  std::size_t i = 0;
  for (std::size_t s = 0; s < slices && i < pts.size(); ++s) {
    const double end = t0 + w * static_cast<double>(s + 1);
    const std::size_t first = i;
    std::size_t lo = i, hi = i;
    while (i < pts.size() && (pts[i].first < end || s + 1 == slices)) {
      if (pts[i].second < pts[lo].second) lo = i;
      if (pts[i].second > pts[hi].second) hi = i;
      ++i;
    }
    if (i == first) continue;
    std::vector<std::size_t> keep{first, lo, hi, i - 1};
    std::sort(keep.begin(), keep.end());
    keep.erase(std::unique(keep.begin(), keep.end()), keep.end());
    for (const std::size_t k : keep) out.push_back(pts[k]);
  }
  return out;
}

}  // namespace

int node_level(std::string_view state) {
  if (state == "operational") return 5;
  if (state == "starting") return 4;
  if (state == "configuring") return 3;
  if (state == "waiting-for-boot-up") return 2;
  if (state == "idle") return 1;
  if (state == "missing") return 0;
  return -1;  // refused
}

double PlotData::seconds(std::int64_t wall_us) {
  if (t0_ < 0) t0_ = wall_us;
  last_ = std::max(last_, static_cast<double>(wall_us - t0_) / 1e6);
  return static_cast<double>(wall_us - t0_) / 1e6;
}

void PlotData::begin_run(const std::string& name) {
  if (t0_ >= 0) markers_.push_back(Marker{last_, "run", "run " + name});
  // Bands still open end where the previous run ended.
  for (auto& [fe, s] : fe_status_open_) bands_.push_back(Band{fe, "", s.first, s.second, last_});
  fe_status_open_.clear();
  for (auto& [sub, s] : fault_open_) bands_.push_back(Band{"", sub, sub + ": " + s.first, s.second, last_});
  fault_open_.clear();
  pending_run_ = name;
}

void PlotData::close_band(std::map<std::string, std::pair<std::string, double>>& open, const std::string& key, double t,
                          const std::string& fe) {
  const auto it = open.find(key);
  if (it == open.end()) return;
  bands_.push_back(Band{fe, fe.empty() ? key : "", fe.empty() ? key + ": " + it->second.first : it->second.first,
                        it->second.second, t});
  open.erase(it);
}

void PlotData::add(std::int64_t wall_us, std::string_view text) {
  const double t = seconds(wall_us);
  if (!pending_run_.empty()) {
    markers_.push_back(Marker{t, "run", "run " + pending_run_});
    pending_run_.clear();
  }
  const auto w = split(text);
  const std::string_view kind = w[0];
  if (kind == "fe" && w.size() >= 3) {
    const std::string fe(w[1]);
    const std::string status(w[2]);
    auto& fields = fields_[fe];
    for (std::size_t i = 3; i < w.size(); ++i) {
      const auto eq = w[i].find('=');
      if (eq == std::string_view::npos) continue;
      const std::string field(w[i].substr(0, eq));
      const std::string value(w[i].substr(eq + 1));
      fields[field].push_back(Point{t, std::strtod(value.c_str(), nullptr)});
    }
    const auto open = fe_status_open_.find(fe);
    if (open != fe_status_open_.end() && open->second.first != status) close_band(fe_status_open_, fe, t, fe);
    if (status != "valid" && !fe_status_open_.contains(fe)) fe_status_open_[fe] = {status, t};
  } else if (kind == "node" && w.size() >= 3) {
    nodes_[std::string(w[1])].push_back(Point{t, static_cast<double>(node_level(w[2]))});
    markers_.push_back(Marker{t, "node", std::string(text.substr(5))});
  } else if (kind == "fault" && w.size() >= 3) {
    const std::string sub(w[1]);
    const auto reason = text.substr(std::min(text.size(), 6 + w[1].size() + 1 + w[2].size() + 1));
    if (w[2] == "raised") {
      if (!fault_open_.contains(sub)) fault_open_[sub] = {std::string(reason), t};
    } else {
      close_band(fault_open_, sub, t, "");
    }
    markers_.push_back(Marker{t, "fault", std::string(text.substr(6))});
  } else if (kind == "emcy" || kind == "emcy_sent") {
    markers_.push_back(Marker{t, std::string(kind), std::string(text)});
  } else if (kind == "indicators" || kind == "display" || kind == "subdevice_command" || kind == "nmt" ||
             kind == "outcome" || kind == "bus" || kind == "start") {
    markers_.push_back(Marker{t, "command", std::string(text)});
  } else if (kind == "gap") {
    markers_.push_back(Marker{t, "gap", std::string(text)});
  }
}

std::vector<std::string> PlotData::series_names() const {
  std::vector<std::string> out;
  for (const auto& [fe, fields] : fields_)
    for (const auto& [field, pts] : fields) out.push_back(fe + "." + field);
  for (const auto& [sub, pts] : nodes_) out.push_back("node " + sub);
  return out;
}

std::vector<PlotData::PlacedBand> PlotData::placed_bands() const {
  std::vector<PlacedBand> out;
  const auto place = [&](const std::string& fe, const std::string& sub, const std::string& what, double from,
                         double to) {
    std::vector<std::string> on;
    if (!sub.empty() && feeds_.contains(sub)) on.assign(feeds_.at(sub).begin(), feeds_.at(sub).end());
    out.push_back(PlacedBand{fe, std::move(on), what, from, to});
  };
  for (const Band& b : bands_) place(b.fe, b.subdevice, b.what, b.from, b.to);
  for (const auto& [fe, s] : fe_status_open_) place(fe, "", s.first, s.second, last_);
  for (const auto& [sub, s] : fault_open_) place("", sub, sub + ": " + s.first, s.second, last_);
  return out;
}

std::vector<std::pair<double, double>> PlotData::drawn(const std::vector<Point>& pts, std::size_t max_points) const {
  std::vector<std::pair<double, double>> p;
  p.reserve(pts.size() + 1);
  for (const auto& q : pts) p.emplace_back(q.t, q.v);
  if (!p.empty() && p.back().first < last_) p.emplace_back(last_, p.back().second);  // held to the end
  return thin(p, max_points);
}

namespace {

// The page around Chart.js and the data: its style, its body, and the script that draws the
// charts from the data (bands and markers by a small plugin: Chart.js 3 has no annotations).
constexpr std::string_view kPageStyle = R"html(<style>
body { font-family: sans-serif; margin: 1em; background: #fff; }
h1 { font-size: 1.2em; } h2 { font-size: 1em; margin: 1.2em 0 0.2em; }
.chart { position: relative; height: 220px; width: 100%; }
.legend span { display: inline-block; margin-right: 1.2em; font-size: 0.85em; }
table { border-collapse: collapse; font-size: 0.85em; } td { padding: 1px 8px; border-bottom: 1px solid #eee; }
</style>
<script>
)html";
constexpr std::string_view kPageBody = R"html(
</script>
</head><body>
<h1 id="title"></h1>
<div class="legend"><span style="background:rgba(255,165,0,0.25)">stale</span><span style="background:rgba(220,0,0,0.2)">error / not available</span><span style="background:rgba(120,120,120,0.25)">offline</span><span style="background:rgba(160,0,160,0.15)">sub-device fault</span><span style="color:#d00">| EMCY received</span><span style="color:#06c">| EMCY sent</span><span style="color:#080">| command</span></div>
<div id="charts"></div>
<h2>Events</h2><table id="events"></table>
<pre id="check"></pre>
<script id="oegw-data" type="application/json">)html";
constexpr std::string_view kPageScript = R"html(</script>
<script>
(function () {
  const data = JSON.parse(document.getElementById('oegw-data').textContent);
  document.getElementById('title').textContent = data.title;
  const when = (t) => { const d = new Date(data.t0 / 1000 + t * 1000); return d.toLocaleTimeString() + '.' + String(d.getMilliseconds()).padStart(3, '0'); };
  const bandColour = (w) => w.includes(':') ? 'rgba(160,0,160,0.15)' : w === 'stale' ? 'rgba(255,165,0,0.25)' : w === 'offline' ? 'rgba(120,120,120,0.25)' : 'rgba(220,0,0,0.2)';
  const markColour = { emcy: '#d00', emcy_sent: '#06c', command: '#080', gap: '#000', run: '#000', fault: '#a0a', node: '#999' };
  // Bands behind the lines, markers over them (a small plugin: Chart.js 3 has no annotations).
  const overlay = {
    id: 'oegwOverlay',
    beforeDatasetsDraw(chart) {
      const x = chart.scales.x, a = chart.chartArea, ctx = chart.ctx;
      for (const b of chart.options.oegwBands || []) {
        ctx.fillStyle = bandColour(b.what);
        const x0 = x.getPixelForValue(b.from), x1 = x.getPixelForValue(b.to);
        ctx.fillRect(Math.max(x0, a.left), a.top, Math.max(Math.min(x1, a.right) - Math.max(x0, a.left), 1), a.bottom - a.top);
      }
    },
    afterDatasetsDraw(chart) {
      const x = chart.scales.x, a = chart.chartArea, ctx = chart.ctx;
      for (const m of chart.options.oegwMarkers || []) {
        const px = x.getPixelForValue(m.t);
        if (px < a.left || px > a.right) continue;
        ctx.strokeStyle = markColour[m.kind] || '#000';
        ctx.beginPath(); ctx.moveTo(px, a.top); ctx.lineTo(px, a.bottom); ctx.stroke();
      }
    }
  };
  Chart.register(overlay);
  const palette = ['#1f77b4', '#ff7f0e', '#2ca02c', '#d62728', '#9467bd', '#8c564b', '#e377c2', '#7f7f7f', '#bcbd22', '#17becf'];
  const check = [];
  const axis = { type: 'linear', min: 0, max: data.end, ticks: { callback: (v) => when(v) } };
  const charts = document.getElementById('charts');
  const markers = data.markers.filter((m) => m.kind === 'emcy' || m.kind === 'emcy_sent' || m.kind === 'command' || m.kind === 'gap' || m.kind === 'run');
  const makeChart = (heading, datasets, bands, extra) => {
    const h = document.createElement('h2'); h.textContent = heading; charts.appendChild(h);
    const div = document.createElement('div'); div.className = 'chart'; charts.appendChild(div);
    const canvas = document.createElement('canvas'); div.appendChild(canvas);
    const chart = new Chart(canvas, {
      type: 'line', data: { datasets },
      options: Object.assign({ animation: false, responsive: true, maintainAspectRatio: false, parsing: false, normalized: true,
        elements: { point: { radius: 0 }, line: { borderWidth: 1.5, stepped: true } },
        scales: { x: axis }, plugins: { legend: { position: 'right' } }, oegwBands: bands, oegwMarkers: markers }, extra || {})
    });
    check.push(heading + ': ' + chart.data.datasets.map((d) => d.label + ' (' + d.data.length + ' points)').join(', ') + '; bands ' + bands.map((b) => b.what).join(', '));
  };
  for (const fe of data.fes) {
    const ds = fe.series.map((s, i) => ({ label: s.name, data: s.points.map((p) => ({ x: p[0], y: p[1] })), borderColor: palette[i % palette.length], backgroundColor: palette[i % palette.length] }));
    makeChart(fe.fe, ds, data.bands.filter((b) => b.fe === fe.fe || (b.fe === '' && (b.on.length === 0 || b.on.includes(fe.fe)))));
  }
  if (data.nodes.length) {
    const ds = data.nodes.map((s, i) => ({ label: s.name, data: s.points.map((p) => ({ x: p[0], y: p[1] })), borderColor: palette[i % palette.length], backgroundColor: palette[i % palette.length] }));
    const names = { 5: 'operational', 4: 'starting', 3: 'configuring', 2: 'waiting for boot-up', 1: 'idle', 0: 'missing', '-1': 'refused' };
    makeChart('sub-devices (node state)', ds, data.bands.filter((b) => b.fe === ''), { scales: { x: axis, y: { min: -1.5, max: 5.5, ticks: { stepSize: 1, callback: (v) => names[v] || '' } } } });
  }
  const table = document.getElementById('events');
  for (const m of data.markers) {
    if (m.kind === 'node' && data.markers.length > 2000) continue;
    const tr = document.createElement('tr');
    tr.innerHTML = '<td></td><td></td><td></td>';
    tr.children[0].textContent = when(m.t); tr.children[1].textContent = m.kind; tr.children[2].textContent = m.text;
    tr.style.color = markColour[m.kind] || '#000';
    table.appendChild(tr);
  }
  check.push('markers: ' + data.markers.length + ' (emcy ' + data.markers.filter((m) => m.kind === 'emcy').length + ', emcy_sent ' + data.markers.filter((m) => m.kind === 'emcy_sent').length + ', command ' + data.markers.filter((m) => m.kind === 'command').length + ')');
  document.getElementById('check').textContent = check.join('\n');
  document.body.setAttribute('data-oegw-plot', 'drawn');
})();
</script>
</body></html>
)html";

}  // namespace

std::string PlotData::html_data(const std::string& title, std::size_t max_points) const {
  using nlohmann::json;
  json data;
  data["title"] = title;
  data["t0"] = t0_;
  data["end"] = last_;
  json fes = json::array();
  for (const auto& [fe, fields] : fields_) {
    json series = json::array();
    for (const auto& [field, pts] : fields) {
      json xy = json::array();
      for (const auto& [x, y] : drawn(pts, max_points)) xy.push_back(json::array({x, y}));
      series.push_back(json{{"name", fe + "." + field}, {"points", xy}});
    }
    fes.push_back(json{{"fe", fe}, {"series", series}});
  }
  data["fes"] = fes;
  json bands = json::array();
  for (const PlacedBand& b : placed_bands())
    bands.push_back(json{{"fe", b.fe}, {"on", b.on}, {"what", b.what}, {"from", b.from}, {"to", b.to}});
  data["bands"] = bands;
  json nodes = json::array();
  for (const auto& [sub, pts] : nodes_) {
    json xy = json::array();
    for (const auto& p : pts) xy.push_back(json::array({p.t, p.v}));
    if (!pts.empty()) xy.push_back(json::array({last_, pts.back().v}));
    nodes.push_back(json{{"name", sub}, {"points", xy}});
  }
  data["nodes"] = nodes;
  json markers = json::array();
  for (const Marker& m : markers_) markers.push_back(json{{"t", m.t}, {"kind", m.kind}, {"text", m.text}});
  data["markers"] = markers;

  // "</script>" inside the data would end the script element: JSON allows "<\/".
  std::string data_text = data.dump();
  for (std::size_t p = 0; (p = data_text.find("</", p)) != std::string::npos; p += 3) data_text.replace(p, 2, "<\\/");
  return data_text;
}

bool PlotData::write_html(const std::filesystem::path& out, const std::string& title, std::string& error,
                          const std::filesystem::path& chart_js, std::size_t max_points) const {
  std::ifstream js(chart_js, std::ios::binary);
  if (!js) {
    error = fmt::format(
        "{}: cannot be read: the plot draws with Chart.js from Debian's libjs-chart.js (apt-get install "
        "libjs-chart.js)",
        chart_js.string());
    return false;
  }
  std::stringstream script;
  script << js.rdbuf();
  const std::string data_text = html_data(title, max_points);

  std::ostringstream f;
  std::string escaped;
  for (const char c : title) escaped += c == '<' ? "&lt;" : c == '>' ? "&gt;" : c == '&' ? "&amp;" : std::string(1, c);
  f << R"html(<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>)html"
    << escaped << "</title>\n"
    << kPageStyle << script.str() << kPageBody << data_text << kPageScript;
  return write_plot_file(out, f.str(), error);
}

bool write_plot_file(const std::filesystem::path& out, std::string_view text, std::string& error) {
  std::ofstream f(out, std::ios::binary | std::ios::trunc);
  if (f) f.write(text.data(), static_cast<std::streamsize>(text.size()));
  f.close();
  if (!f) {
    error = out.string() + ": cannot be written";
    return false;
  }
  return true;
}

}  // namespace oegw::gateway::record
