#include "gateway/record/replay.hpp"

#include <unistd.h>

#include <cstdlib>
#include <ctime>
#include <deque>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>
#include <stdexcept>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "canopen/301/storage.hpp"
#include "canopen/state.hpp"
#include "gateway/record/gateway_recorder.hpp"
#include "gateway/record/plot.hpp"

namespace oegw::gateway::record {

namespace fs = std::filesystem;

namespace {

std::string_view first_word(std::string_view s) { return s.substr(0, s.find(' ')); }

bool is_input(std::string_view kind) {
  return kind == "start" || kind == "tick" || kind == "bus" || kind == "indicators" || kind == "display" ||
         kind == "subdevice_command" || kind == "nmt";
}
// `state`: a segment's state (format 2), which the exact replay checks (check_state()).
bool is_skipped(std::string_view kind) { return kind == "segment" || kind == "meta" || kind == "state"; }

// A control request that changes nothing in the gateway (docs/guides/black-box.md).
bool read_only_control(std::string_view text) {
  const auto json_text = text.substr(text.find(' ') + 1);
  const auto j = nlohmann::json::parse(json_text, nullptr, false);
  if (!j.is_object() || !j.contains("command") || !j["command"].is_string()) return false;
  const std::string c = j["command"];
  return c == "status" || c == "record_keep" || c == "info" || c == "events";
}

std::vector<std::string> words(std::string_view s) {
  std::vector<std::string> out;
  std::size_t at = 0;
  while (at < s.size()) {
    const auto sp = s.find(' ', at);
    out.emplace_back(s.substr(at, sp == std::string_view::npos ? std::string_view::npos : sp - at));
    if (sp == std::string_view::npos) break;
    at = sp + 1;
  }
  return out;
}

std::optional<mapping::CommandSource> source_named(std::string_view s) {
  for (const auto c : {mapping::CommandSource::Canopen, mapping::CommandSource::Dds, mapping::CommandSource::Lcm})
    if (mapping::to_string(c) == s) return c;
  return std::nullopt;
}

std::optional<canopen::BusEvent> bus_event_named(std::string_view s) {
  for (int i = 0; i <= static_cast<int>(canopen::BusEvent::InterfaceDown); ++i) {
    const auto e = static_cast<canopen::BusEvent>(i);
    std::string w(canopen::to_string(e));
    for (char& c : w)
      if (c == ' ') c = '-';
    if (w == s) return e;
  }
  return std::nullopt;
}

// Feeds one recorded input that is no frame; false and `error` when it cannot be read.
bool feed_event(Gateway& gw, std::string_view text, canopen::TimePoint t, std::string& error) {
  if (text == "tick") {  // most of them
    gw.advance(t);
    return true;
  }
  const auto w = words(text);
  const auto num = [&](std::size_t i, int base) -> std::optional<long long> {
    if (i >= w.size()) return std::nullopt;
    char* end = nullptr;
    const long long v = std::strtoll(w[i].c_str(), &end, base);
    if (end == w[i].c_str() || *end != '\0') return std::nullopt;
    return v;
  };
  const std::string& k = w[0];
  if (k == "start") {
    (void)gw.start(t);
  } else if (k == "tick") {
    gw.advance(t);
  } else if (k == "bus" && w.size() == 3) {
    const auto e = bus_event_named(w[2]);
    if (!e) return error = "unknown bus event '" + w[2] + "'", false;
    if (w[1] == "up") gw.on_upstream_bus_event(*e, t);
    else gw.on_downstream_bus_event(*e, t);
  } else if (k == "indicators" && w.size() == 4) {
    const auto n = num(1, 10);
    const auto src = source_named(w[3]);
    if (!n || !src || w[2].empty()) return error = "cannot read '" + std::string(text) + "'", false;
    gw.command_indicators(static_cast<std::uint8_t>(*n), std::strtoull(w[2].c_str(), nullptr, 16), t, *src);
  } else if (k == "display" && w.size() == 4) {
    const auto n = num(1, 10);
    const auto src = source_named(w[3]);
    std::array<std::int16_t, 12> p{};
    std::stringstream ss(w[2]);
    std::string item;
    std::size_t i = 0;
    while (std::getline(ss, item, ',') && i < 12) p[i++] = static_cast<std::int16_t>(std::atoi(item.c_str()));
    if (!n || !src || i != 12) return error = "cannot read '" + std::string(text) + "'", false;
    gw.command_display(static_cast<std::uint8_t>(*n), p, t, *src);
  } else if (k == "subdevice_command" && w.size() == 3) {
    gw.subdevice_command(w[1], w[2], t);
  } else if (k == "nmt" && w.size() == 3) {
    const auto node = num(1, 16), cs = num(2, 16);
    if (!node || !cs) return error = "cannot read '" + std::string(text) + "'", false;
    (void)gw.downstream_nmt(canopen::NodeId{static_cast<std::uint8_t>(*node)}, static_cast<canopen::NmtCommand>(*cs),
                            t);
  } else {
    error = "cannot read input '" + std::string(text) + "'";
    return false;
  }
  return true;
}

// What the replayed gateway sent and decided, in order, for the comparison.
struct Produced {
  bool frame = false;
  Side side = Side::Up;
  canopen::CanFrame f;
  std::string text;
};

class Capture final : public RecordSink {
 public:
  std::deque<Produced> q;
  std::function<void(const Produced&, canopen::TimePoint)> observe;
  void frame(Side side, Direction d, const canopen::CanFrame& f, canopen::TimePoint t) override {
    if (d == Direction::Rx) return;  // the input itself
    q.push_back(Produced{true, side, f, {}});
    if (observe) observe(q.back(), t);
  }
  void event(canopen::TimePoint t, std::string_view text) override {
    const auto kind = first_word(text);
    if (is_input(kind) || kind == "control" || kind == "reload") return;
    q.push_back(Produced{false, Side::Up, {}, std::string(text)});
    if (observe) observe(q.back(), t);
  }
};

struct Printer {
  const ReplayOptions& o;
  const mapping::Config& config;
  std::int64_t run_start_wall = -1;

  [[nodiscard]] bool in_time(std::int64_t wall) const {
    return (!o.from_us || wall >= *o.from_us) && (!o.to_us || wall <= *o.to_us);
  }
  [[nodiscard]] std::optional<std::uint8_t> node_of(const std::string& sub) const {
    for (const auto& s : config.subdevices)
      if (s.name == sub) return s.node_id;
    return std::nullopt;
  }
  [[nodiscard]] bool wanted_text(std::string_view text) const {
    const auto kind = first_word(text);
    if (kind == "tick" || is_skipped(kind)) return false;
    if (kind == "log" && !o.logs) return false;
    const auto w = words(text);
    if (!o.fe.empty()) {
      const bool fe_line = kind == "fe" && w.size() > 1 && w[1] == o.fe;
      const bool command =
          (kind == "indicators" || kind == "display") && w.size() > 1 && std::string(kind) + "." + w[1] == o.fe;
      if (!fe_line && !command && !(kind == "log" && text.find(o.fe) != std::string_view::npos)) return false;
    }
    if (!o.subdevice.empty()) {
      const bool named = (kind == "node" || kind == "fault" || kind == "emcy" || kind == "subdevice_command") &&
                         w.size() > 1 && w[1] == o.subdevice;
      if (!named && !(kind == "log" && text.find(o.subdevice) != std::string_view::npos)) return false;
    }
    return true;
  }
  [[nodiscard]] bool wanted_frame(Side side, const canopen::CanFrame& f) const {
    if (!o.frames) return false;
    if (!o.fe.empty()) return false;
    if (!o.subdevice.empty()) {
      const auto n = node_of(o.subdevice);
      return n && side == Side::Down && (f.id & 0x7F) == *n && f.id != 0;
    }
    return true;
  }
  void line(std::int64_t wall, std::string_view text) {
    if (run_start_wall < 0) run_start_wall = wall;
    if (o.timeline == nullptr || !in_time(wall)) return;
    *o.timeline << time_of_day(wall) << fmt::format(" {:+12.6f} ", (wall - run_start_wall) / 1e6) << text << '\n';
  }
};

std::string frame_text(Direction d, const std::string& iface, const canopen::CanFrame& f) {
  return fmt::format("{} {} {}", d == Direction::Rx ? 'R' : 'T', iface, f.to_string());
}

}  // namespace

std::string time_of_day(std::int64_t wall_us) {
  return fmt::format("{}.{:06}", wall_text(wall_us, "%H:%M:%S", false), wall_us % 1000000);
}

bool own_frame(Gateway& gw, Side side, const canopen::CanFrame& f) {
  if (f.extended) return false;
  const std::uint32_t id = f.id;
  if (side == Side::Down) {
    if (id == 0x000 || id == 0x7E5) return true;
    if (id == 0x080) return true;  // SYNC: the gateway is the downstream SYNC producer
    if (id >= 0x601 && id <= 0x67F) return true;
    const std::uint32_t fc = id & 0x780;
    return (fc == 0x200 || fc == 0x300 || fc == 0x400 || fc == 0x500) && (id & 0x7F) != 0;
  }
  const std::uint8_t node = gw.upstream().node().node_id().value();
  if (id == 0x700u + node || id == 0x80u + node || id == 0x580u + node || id == 0x7E4) return true;
  const auto& od = gw.upstream().od();
  // Its TPDOs (1800h..19FFh:01, valid ones) and its extra SDO servers' responses (1201h..:02).
  for (std::uint16_t i = 0x1800; i < 0x1A00; ++i) {
    if (od.find(i) == nullptr) continue;
    const auto cob = od.get<std::uint32_t>(i, 1);
    if ((cob & 0x80000000u) == 0 && (cob & 0x7FF) == id) return true;
  }
  for (std::uint16_t i = 0x1201; i < 0x1280; ++i) {
    if (od.find(i) == nullptr) continue;
    const auto cob = od.get<std::uint32_t>(i, 2);
    if ((cob & 0x80000000u) == 0 && (cob & 0x7FF) == id) return true;
  }
  return false;
}

namespace {

class RunReplay {
 public:
  RunReplay(const Run& run, const mapping::Config& config, const ReplayOptions& o)
      : run_(run), config_(config), o_(o), printer_{o, config} {
    report_.run = run.name;
  }

  RunReport go() {
    // The store the run started with, in a folder of the replay's own: the replay never
    // writes the gateway's store.
    char tmpl[] = "/tmp/oegw-replay-XXXXXX";
    const char* made = ::mkdtemp(tmpl);
    if (made == nullptr) throw std::runtime_error("cannot make a temporary folder for the replay's store");
    tmp_ = made;
    GatewayOptions opt = o_.gateway;
    opt.store_path = tmp_ / "upstream.store";
    std::error_code ec;
    if (!run_.store_copy.empty()) fs::copy_file(run_.store_copy, tmp_ / "upstream.store", ec);
    if (!run_.lss_copy.empty()) fs::copy_file(run_.lss_copy, tmp_ / "upstream.store.lss", ec);
    // The first segment, read once: what it begins with decides how the run is replayed.
    std::optional<SegmentReader> first;
    if (!run_.segments.empty()) first.emplace(run_.segments.front());
    // The recorded gateway options (its `meta gateway` line) go first.
    if (const auto bus_share = recorded_bus_share(first)) opt.sdo_bus_share = *bus_share;
    const bool has_start = !run_.plain() && first && leading(*first, "start");
    // Without the run's start (its first segments left the ring): the first segment's state,
    // where the gateway was taken between two of its calls, is where an exact replay begins.
    const std::optional<Entry> state_start =
        !o_.fresh && !run_.plain() && first && !has_start ? leading(*first, "state") : std::nullopt;
    mode_ = o_.fresh || run_.plain()   ? ReplayMode::Fresh
            : has_start || state_start ? ReplayMode::Exact
                                       : ReplayMode::Recorded;
    if (mode_ == ReplayMode::Fresh && !run_.plain())
      report_.notes.push_back(
          fmt::format("--fresh: the recorded inputs re-run on a new gateway, nothing compared{}",
                      has_start ? "" : " (the recording does not reach back to the gateway's start)"));
    if (mode_ != ReplayMode::Recorded) {
      // A fresh gateway's own requests go nowhere, their answers come as the log has them:
      // paced, a request would go out after the answer the log holds for it.
      if (mode_ == ReplayMode::Fresh) opt.sdo_bus_share = 0;
      rec_ = std::make_unique<GatewayRecorder>(capture_);
      opt.tap = rec_.get();
      gw_ = std::make_unique<Gateway>(
          config_, [](const canopen::CanFrame&) {}, [](const canopen::CanFrame&) {}, opt);
      if (state_start) begin_in(*state_start);
    }
    if (mode_ == ReplayMode::Recorded && !run_.plain() && !has_start)
      report_.notes.push_back(
          fmt::format("the recording does not reach back to the gateway's start (its first segments left the "
                      "ring) and {}: shown as recorded, nothing re-run or compared; --fresh re-runs the recorded "
                      "inputs on a new gateway",
                      no_state_why_.empty() ? "its first segment begins with no state" : no_state_why_));
    report_.mode = mode_;
    if (!run_.mapping_copy.empty() && !config_.file.empty()) {
      std::ifstream a(run_.mapping_copy), b(config_.file);
      std::stringstream sa, sb;
      sa << a.rdbuf();
      sb << b.rdbuf();
      if (sa.str() != sb.str())
        report_.notes.push_back(fmt::format("{}: the recording was made with another mapping file ({}){}", config_.file,
                                            run_.mapping_copy.string(),
                                            mode_ == ReplayMode::Exact ? ": a divergence may come from the difference"
                                            : mode_ == ReplayMode::Recorded
                                                ? ": the timeline shown is what that file made"
                                                : ""));
    }
    capture_.observe = [this](const Produced& p, canopen::TimePoint t) { produced(p, t); };
    for (const Segment& s : run_.segments) {
      std::optional<SegmentReader> next;
      SegmentReader& r = first ? *first : next.emplace(s);
      if (!r.head().up_iface.empty()) {
        up_ = r.head().up_iface;
        down_ = r.head().down_iface;
      }
      offset_ = r.head().offset_us;
      const auto& problems = r.head().problems;
      const std::size_t told = problems.size();  // the events file's; the frames file's come with each()
      for (std::size_t i = 0; i < told; ++i) report_.notes.push_back(problems[i]);
      r.each([this](const Entry& e) {
        switch (mode_) {
          case ReplayMode::Exact: exact(e); break;
          case ReplayMode::Recorded: recorded(e); break;
          case ReplayMode::Fresh: fresh(e); break;
        }
      });
      for (std::size_t i = told; i < problems.size(); ++i) report_.notes.push_back(problems[i]);
      first.reset();
    }
    if (mode_ == ReplayMode::Exact && comparing() && !capture_.q.empty())
      report_.notes.push_back(
          fmt::format("the recording ends inside the gateway's last call: {} output(s) of the replay "
                      "after its end not compared",
                      capture_.q.size()));
    gw_.reset();
    rec_.reset();
    fs::remove_all(tmp_, ec);
    return report_;
  }

 private:
  [[nodiscard]] bool comparing() const { return !report_.divergence && report_.stopped.empty(); }

  std::optional<double> recorded_bus_share(const std::optional<SegmentReader>& first) const {
    if (run_.plain() || !first) return std::nullopt;
    for (const Entry& e : first->events()) {
      if (e.kind != Entry::Kind::Event) continue;
      const auto p = e.text.find("meta gateway ");
      if (p != 0) continue;
      const auto q = e.text.find("sdo_bus_share=");
      if (q != std::string::npos) return std::atof(e.text.c_str() + q + 14);
    }
    return std::nullopt;
  }

  // The first segment's leading `kind` line: before any frame, input or decision, past its head
  // (`segment`, `meta`, `state` lines; for a `state`, a `gap` the writer tells before it: records
  // lost before the state).
  static std::optional<Entry> leading(const SegmentReader& first, std::string_view kind) {
    for (const Entry& e : first.events()) {
      if (e.frame.id != 0) return std::nullopt;  // one @N past 0 comes after a frame
      const auto k = first_word(e.text);
      if (k == kind) return e;
      if (!is_skipped(k) && !(kind == "state" && k == "gap")) return std::nullopt;
    }
    return std::nullopt;
  }

  // The replayed gateway put in the recorded state `e` in place of its start; when it cannot
  // be (`state none`, a damaged line, a state of another mapping file or version), the run is
  // shown as recorded and why is noted.
  void begin_in(const Entry& e) {
    std::string error;
    const std::optional<std::string> text = parse_state_event(e.text, error);
    if (!text && error.rfind("none ", 0) == 0) {  // "none (WHY)"
      no_state_why_ = "its first segment begins with no state " + error.substr(5);
      mode_ = ReplayMode::Recorded;
      gw_.reset();
      rec_.reset();
      return;
    }
    try {
      if (!text) throw canopen::StateError(error);
      const canopen::StateReader r = canopen::StateReader::parse(*text);
      give_store(r.in("device").in("node").in("store"));
      gw_->import_state(r);
      if (const auto left = r.unread(); !left.empty())
        throw canopen::StateError(
            fmt::format("{} key(s) this gateway does not take, the first '{}'", left.size(), left.front()));
    } catch (const std::exception& x) {
      no_state_why_ = fmt::format("its first segment's state ({}) cannot be taken: {}", e.where(), x.what());
      mode_ = ReplayMode::Recorded;
      gw_.reset();
      rec_.reset();
      return;
    }
    before_start_ = true;
    report_.from_state = time_of_day(e.wall_us) + " (" + e.where() + ")";
  }

  // The upstream store file as the recorded gateway last read or wrote it (its state's
  // device.node.store), in place of the run's first copy: a reset inside the window applies
  // what the store held then, also after a store command before the window. (The LSS store is
  // read at power-on only.)
  void give_store(const canopen::StateReader& s) {
    if (!s.has("file")) return;  // a device without a store
    const fs::path store = tmp_ / "upstream.store";
    std::error_code ec;
    fs::remove(store, ec);
    const auto seen = s.get<canopen::PlainFile::State>("file");
    if (seen == canopen::PlainFile::State::Read) {
      std::ofstream out(store, std::ios::binary);
      out << s.text("text", std::numeric_limits<std::size_t>::max());  // Node::import_state bounds it
      if (!out.flush()) throw std::runtime_error("cannot write the replay's store " + store.string());
    } else if (seen == canopen::PlainFile::State::Refused) {
      // Refused as the run's was (a link is never followed), though for another reason: a line
      // that names the store's path or the reason differs, and a save of all groups, which the
      // store takes over an unreadable file and refuses over a link, is answered otherwise.
      fs::create_symlink("refused", store, ec);
      report_.notes.push_back(
          fmt::format("the run's store was refused ({}): the replay's is a symbolic link, refused too; a line "
                      "naming the store's path or the reason, and a save of all groups, may diverge",
                      s.text("error", std::numeric_limits<std::size_t>::max())));
    }
  }

  std::optional<Side> side_of(const std::string& iface) {
    if (iface == up_ || iface == config_.upstream.interface || iface == "up") return Side::Up;
    if (iface == down_ || iface == config_.downstream.interface || iface == "down") return Side::Down;
    // A plain log of one bus: the downstream one (its only other name).
    if (run_.plain()) {
      if (lone_iface_.empty()) lone_iface_ = iface;
      if (iface == lone_iface_) return Side::Down;
    }
    if (unknown_ifaces_.insert(iface).second)
      report_.notes.push_back(fmt::format("frames on interface '{}' skipped: neither {} nor {} (the mapping file's)",
                                          iface, config_.upstream.interface, config_.downstream.interface));
    return std::nullopt;
  }

  [[nodiscard]] const std::string& iface_name(Side s) const {
    return s == Side::Up ? (up_.empty() ? config_.upstream.interface : up_)
                         : (down_.empty() ? config_.downstream.interface : down_);
  }

  void show(std::int64_t wall, std::string_view text) {
    if (printer_.run_start_wall < 0) printer_.run_start_wall = wall;
    if (o_.timeline != nullptr && printer_.wanted_text(text)) printer_.line(wall, text);
    if (o_.plot != nullptr) o_.plot->add(wall, text);
  }
  void show_frame(std::int64_t wall, Side side, Direction d, const canopen::CanFrame& f) {
    if (printer_.run_start_wall < 0) printer_.run_start_wall = wall;
    if (o_.timeline != nullptr && printer_.wanted_frame(side, f))
      printer_.line(wall, frame_text(d, iface_name(side), f));
  }

  // The replay's outputs: shown in fresh mode (in exact mode the recording's are shown).
  void produced(const Produced& p, canopen::TimePoint t) {
    if (p.frame) ++report_.frames_out;
    else ++report_.decisions;
    if (mode_ == ReplayMode::Exact) return;
    const std::int64_t wall = t.time_since_epoch().count() + offset_;
    if (p.frame) show_frame(wall, p.side, Direction::Tx, p.f);
    else show(wall, p.text);
  }

  void stop(const Entry& e, std::string why) {
    if (!comparing()) return;
    report_.stopped = fmt::format("{} ({}): {}", time_of_day(e.wall_us), e.where(), why);
  }

  std::string when(const Entry& e) const {
    return fmt::format("{} ({:.6f} s into the run)", time_of_day(e.wall_us),
                       (e.wall_us - std::max<std::int64_t>(printer_.run_start_wall, 0)) / 1e6);
  }

  void diverge(const Entry& e, std::string recorded, std::string replayed) {
    const std::string after =
        last_input_ ? last_input_->text_line() + " (" + last_input_->where() + ")" : std::string("(none yet)");
    report_.divergence = Divergence{when(e), after, std::move(recorded), std::move(replayed)};
  }

  std::string describe(const Produced& p) const {
    return p.frame ? frame_text(Direction::Tx, iface_name(p.side), p.f) : p.text;
  }

  // Before the input `e`: the replay must have produced nothing the recording lacks.
  void expect_nothing_pending(const Entry& e) {
    if (!comparing() || capture_.q.empty()) return;
    diverge(e, "(nothing more before the next input: " + e.text_line() + ", " + e.where() + ")",
            describe(capture_.q.front()));
  }

  // The recorded output `e` against the replay's next one.
  template <class Same>
  void compare(const Entry& e, const Same& same) {
    if (!comparing()) return;
    if (capture_.q.empty()) {
      diverge(e, e.text_line() + " (" + e.where() + ")", "(nothing: the replayed gateway did not do this)");
      return;
    }
    if (!same(capture_.q.front())) {
      diverge(e, e.text_line() + " (" + e.where() + ")", describe(capture_.q.front()));
      return;
    }
    capture_.q.pop_front();
    ++report_.compared;
  }

  // A frame line of a recording: shown, and its side and direction (nullopt: on neither of the
  // mapping file's buses).
  std::optional<std::pair<Side, Direction>> shown_frame(const Entry& e) {
    const auto side = side_of(e.iface);
    if (!side) return std::nullopt;
    const Direction d = e.direction.value_or(Direction::Rx);
    show_frame(e.wall_us, *side, d, e.frame);
    return std::pair{*side, d};
  }

  void exact(const Entry& e) {
    if (e.kind == Entry::Kind::Frame) {
      const auto shown = shown_frame(e);
      if (!shown) return;
      const Side side = shown->first;
      if (shown->second == Direction::Rx) {
        expect_nothing_pending(e);
        ++report_.inputs;
        ++report_.frames_in;
        last_input_ = e;
        if (side == Side::Up) gw_->on_upstream_frame(e.frame, e.t);
        else gw_->on_downstream_frame(e.frame, e.t);
      } else {
        compare(e, [&](const Produced& p) { return p.frame && p.side == side && p.f == e.frame; });
      }
      return;
    }
    const auto kind = first_word(e.text);
    if (kind == "state") return check_state(e);
    if (is_skipped(kind)) return;
    if (before_start_) return;  // a gap before the state the replay begins in: records lost before it
    show(e.wall_us, e.text);
    if (kind == "gap") return stop(e, "the recording lost records here (" + e.text + "): compared up to it");
    if (kind == "reload")
      return stop(e, "the mapping file was reloaded here (SIGHUP): a replay runs one mapping file, compared up to it");
    if (kind == "control") {
      if (!read_only_control(e.text))
        stop(e, "a control-socket session reached into the gateway (" + e.text.substr(8) +
                    "): not replayed, compared up to it");
      return;
    }
    if (is_input(kind)) {
      expect_nothing_pending(e);
      ++report_.inputs;
      last_input_ = e;
      if (!comparing()) {
        // Still fed, for a timeline that goes on; its outputs are not compared.
        std::string ignored;
        (void)feed_event(*gw_, e.text, e.t, ignored);
        capture_.q.clear();
        return;
      }
      std::string error;
      if (!feed_event(*gw_, e.text, e.t, error)) stop(e, error);
      return;
    }
    compare(e, [&](const Produced& p) { return !p.frame && p.text == e.text; });
    if (!comparing()) capture_.q.clear();
  }

  // A segment's `state` line: the recorded gateway's state there, taken between two of its
  // calls. The replayed gateway, fed the same inputs, must be in it: the first key that differs
  // is a divergence. Where a state was given (also one damaged since), the recorder's FE lines
  // began anew, and so do the replay's; `state none` changed nothing.
  void check_state(const Entry& e) {
    if (before_start_) {  // where the replay began
      before_start_ = false;
      return;
    }
    std::string error;
    const std::optional<std::string> recorded = parse_state_event(e.text, error);
    if (!recorded) {
      if (error.rfind("none ", 0) == 0) return;
      rec_->segment_started();
      report_.notes.push_back(e.where() + ": state not read: " + error);
      return;
    }
    rec_->segment_started();
    if (!comparing()) return;
    if (!capture_.q.empty()) {
      diverge(e, "(nothing more before the segment's state, " + e.where() + ")", describe(capture_.q.front()));
      return;
    }
    if (const std::string why = gw_->busy(); !why.empty()) {
      diverge(e, "the gateway's state (" + e.where() + ")", "a gateway not between calls: " + why);
      return;
    }
    canopen::StateWriter w;
    gw_->export_state(w);
    if (w.text() == *recorded) {
      ++report_.states;
      return;
    }
    // The first line that differs.
    std::size_t at = 0;
    while (at < recorded->size() && at < w.text().size() && (*recorded)[at] == w.text()[at]) ++at;
    const auto line_of = [&](const std::string& t) {
      const std::size_t b = t.rfind('\n', at == 0 ? 0 : at - 1);
      const std::size_t from = b == std::string::npos || at == 0 ? 0 : b + 1;
      const std::size_t end = t.find('\n', from);
      return t.substr(from, end == std::string::npos ? std::string::npos : end - from);
    };
    diverge(e, "state " + line_of(*recorded) + " (" + e.where() + ")", "state " + line_of(w.text()));
  }

  // The recording as it is: its frames (with their direction) and its events, counted.
  void recorded(const Entry& e) {
    if (e.kind == Entry::Kind::Frame) {
      const auto shown = shown_frame(e);
      if (!shown) return;
      if (shown->second == Direction::Rx) {
        ++report_.inputs;
        ++report_.frames_in;
      } else {
        ++report_.frames_out;
      }
      return;
    }
    const auto kind = first_word(e.text);
    if (is_skipped(kind)) return;
    show(e.wall_us, e.text);
    if (is_input(kind)) ++report_.inputs;
    else if (kind != "control" && kind != "reload" && kind != "gap") ++report_.decisions;
  }

  // The event loop's way with the gateway's timers (canopen/io/event_loop.hpp ServiceDriver): a
  // deadline fires at its time, one already past at the loop's time now.
  void advance_to(canopen::TimePoint t) {
    for (int guard = 0; guard < 1000000; ++guard) {
      const auto d = gw_->next_deadline();
      if (!d || *d > t) break;
      clock_ = std::max(clock_, *d);
      gw_->advance(clock_);
    }
    clock_ = std::max(clock_, t);
  }

  void fresh(const Entry& e) {
    if (e.kind == Entry::Kind::Frame) {
      const auto side = side_of(e.iface);
      if (!side) return;
      const bool input = e.direction ? *e.direction == Direction::Rx : !own_frame(*gw_, *side, e.frame);
      if (!input) return;
      if (!started_) {
        clock_ = e.t;
        (void)gw_->start(e.t);
        started_ = true;
      }
      advance_to(e.t);
      show_frame(e.wall_us, *side, Direction::Rx, e.frame);
      ++report_.inputs;
      ++report_.frames_in;
      if (*side == Side::Up) gw_->on_upstream_frame(e.frame, e.t);
      else gw_->on_downstream_frame(e.frame, e.t);
      capture_.q.clear();
      return;
    }
    const auto kind = first_word(e.text);
    if (!is_input(kind) || kind == "start" || kind == "tick" || !started_) return;
    advance_to(e.t);
    show(e.wall_us, e.text);
    std::string ignored;
    (void)feed_event(*gw_, e.text, e.t, ignored);
    ++report_.inputs;
    capture_.q.clear();
  }

  const Run& run_;
  const mapping::Config& config_;
  const ReplayOptions& o_;
  Printer printer_;
  RunReport report_;
  fs::path tmp_;
  Capture capture_;
  std::unique_ptr<Gateway> gw_;
  std::unique_ptr<GatewayRecorder> rec_;
  ReplayMode mode_ = ReplayMode::Fresh;
  bool started_ = false;
  std::string up_, down_, lone_iface_;
  std::optional<Entry> last_input_;  // for a divergence's "after the input …"
  bool before_start_ = false;        // begun in a state whose line is still to come
  std::string no_state_why_;         // why the first segment's state could not be taken
  std::set<std::string> unknown_ifaces_;
  std::int64_t offset_ = 0;
  canopen::TimePoint clock_{};  // fresh mode: the replay's loop time
};

}  // namespace

std::vector<RunReport> replay(const std::vector<Run>& runs, const mapping::Config& config,
                              const ReplayOptions& options) {
  std::vector<RunReport> out;
  if (options.plot != nullptr)
    for (const auto& fe : config.functional_elements)
      for (const auto& b : fe.fields) options.plot->feeds(b.subdevice, mapping::fe_name(fe.id));
  for (const Run& r : runs) {
    if (options.plot != nullptr) options.plot->begin_run(r.name);
    out.push_back(RunReplay(r, config, options).go());
  }
  return out;
}

}  // namespace oegw::gateway::record
