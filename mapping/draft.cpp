#include "mapping/draft.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <map>
#include <optional>
#include <set>
#include <vector>

#include "subdevices/driver_options.hpp"
#include "subdevices/family_identity.hpp"

namespace oegw::mapping {

namespace {

namespace sd = subdevices;
using canopen::NmtState;

std::string hex(std::uint32_t v, int digits) {
  char b[16];
  std::snprintf(b, sizeof b, "%0*X", digits, v);
  return b;
}

// "elobau_mfg_11": the family and the node-ID in hex, a name the mapping file takes as a key.
// A sub-device of the running gateway keeps its mapping-file name.
std::string entry_name(const sd::ScannedNode& n) {
  if (!n.configured_as.empty()) return n.configured_as;
  std::string family = n.family.family.empty() ? "node" : n.family.family;
  std::replace(family.begin(), family.end(), '-', '_');
  std::string id = hex(n.node.value(), 2);
  std::transform(id.begin(), id.end(), id.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return family + "_" + id;
}

std::string state_text(const sd::ScannedNode& n) {
  if (!n.state) return n.booted ? "booted" : "";
  switch (*n.state) {
    case NmtState::Operational: return "operational";
    case NmtState::PreOperational: return "pre-operational";
    case NmtState::Stopped: return "stopped";
    default: return "";
  }
}

// The heartbeat the draft asks of the node: its own 1017h when it produces one, else what was
// heard, else the mapping file's default 100 ms.
struct HeartbeatChoice {
  std::uint16_t ms = 100;
  std::string why;
};
HeartbeatChoice heartbeat_choice(const sd::ScannedNode& n) {
  if (n.producer_heartbeat_ms && *n.producer_heartbeat_ms > 0)
    return {*n.producer_heartbeat_ms, n.configured_as.empty() ? "the node's 1017h" : "the running gateway's"};
  if (n.heartbeat_period) {
    const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(*n.heartbeat_period).count();
    if (ms > 0 && ms <= 65535) return {static_cast<std::uint16_t>(ms), "the period heard"};
  }
  return {100, "the node produces none yet; the gateway writes it to 1017h at boot"};
}

// Text wrapped into comment lines of at most 100 columns, each starting with `prefix`.
std::string comment(const std::string& prefix, const std::string& text) {
  return wrap_words(text, 100, prefix, prefix);
}

// FE instances handed out so far, per kind, so that uncommenting every suggestion of every node
// gives each FE once.
struct FeCounters {
  std::map<std::string, int> next;
  std::optional<int> take(const std::string& kind) {
    static const std::map<std::string, int> limit = {{"joystick", 16}, {"pedal", 16},     {"encoder", 8}, {"wheel", 8},
                                                     {"buttons", 8},   {"indicators", 8}, {"display", 8}};
    int& n = next[kind];
    if (n >= limit.at(kind)) return std::nullopt;
    return ++n;
  }
};

std::optional<int> bit_count(const sd::SignalInfo& s) {
  if (s.min != 0 || s.max < 1 || s.unit != "bits") return std::nullopt;
  int n = 0;
  for (std::int64_t v = s.max; v & 1; v >>= 1) ++n;
  if ((std::int64_t{1} << n) - 1 != s.max) return std::nullopt;
  return n;
}

// The suggested FE lines of one node (without the comment mark): its joystick axes and buttons,
// other axes as wheels, analogue values as pedals, positions as encoders, the rest of the
// one-bit and bit-packed inputs as a button cluster, one-bit outputs as indicators and other
// outputs as display parameters (the field table of
// docs/reference/mapping-file.md#functional_elements-kindinstance-field-signal-required-may-be-empty).
std::vector<std::string> fe_lines(const std::string& name, const std::vector<sd::SignalInfo>& signals, FeCounters& fe) {
  using K = sd::SignalKind;
  std::vector<std::string> out;
  std::set<std::string> used;
  auto find = [&](const std::string& n, K kind) -> const sd::SignalInfo* {
    for (const auto& s : signals)
      if (s.name == n && s.kind == kind) return &s;
    return nullptr;
  };
  const auto sig = [&](const std::string& s) { return name + "." + s; };
  // A joystick: x and y axes (z when there is one), buttons[1..k] up to 8.
  if (find("x", K::Axis) && find("y", K::Axis)) {
    if (const auto j = fe.take("joystick")) {
      out.push_back("joystick." + std::to_string(*j) + ":");
      for (const char* axis : {"x", "y", "z"})
        if (find(axis, K::Axis)) {
          out.push_back(std::string("  ") + axis + ": " + sig(axis));
          used.insert(axis);
        }
      int k = 0;
      while (k < 8 && find("buttons[" + std::to_string(k + 1) + "]", K::Button)) ++k;
      if (k > 0) {
        out.push_back("  buttons[1.." + std::to_string(k) + "]: " + sig("buttons[1.." + std::to_string(k) + "]"));
        for (int i = 1; i <= k; ++i) used.insert("buttons[" + std::to_string(i) + "]");
      }
    }
  }
  std::vector<std::string> switches, indicators, parameters;
  int sw = 0, ind = 0, par = 0;
  for (const auto& s : signals) {
    if (used.count(s.name)) continue;
    const auto one = [&](const std::string& kind, const std::string& field) {
      if (const auto i = fe.take(kind)) {
        out.push_back(kind + "." + std::to_string(*i) + ":");
        out.push_back("  " + field + ": " + sig(s.name));
      } else {
        out.push_back("# " + sig(s.name) + ": every " + kind + " FE taken");
      }
    };
    switch (s.kind) {
      case K::Axis: one("wheel", "position"); break;
      case K::Analog: one("pedal", "position"); break;
      case K::Position: one("encoder", "position"); break;
      case K::Speed: out.push_back("# " + sig(s.name) + ": a Speed signal, no FE field takes it"); break;
      case K::Button:
      case K::Digital: {
        const int n = s.kind == K::Button ? 1 : bit_count(s).value_or(0);
        if (n == 0 || sw + n > 64) {
          out.push_back("# " + sig(s.name) + ": " + std::string(sd::to_string(s.kind)) + " " + std::to_string(s.min) +
                        ".." + std::to_string(s.max) + ", no switch field fits it here");
          break;
        }
        const std::string range =
            n == 1 ? std::to_string(sw + 1) : std::to_string(sw + 1) + ".." + std::to_string(sw + n);
        switches.push_back("  switch[" + range + "]: " + sig(s.name));
        sw += n;
        break;
      }
      case K::Output: {
        const auto n = s.min == 0 && s.max == 1 ? std::optional<int>(1) : bit_count(s);
        if (n && ind + *n <= 64) {
          const std::string range =
              *n == 1 ? std::to_string(ind + 1) : std::to_string(ind + 1) + ".." + std::to_string(ind + *n);
          indicators.push_back("  indicator[" + range + "]: " + sig(s.name));
          ind += *n;
        } else if (par < 12) {
          parameters.push_back("  parameter[" + std::to_string(++par) + "]: " + sig(s.name));
        } else {
          out.push_back("# " + sig(s.name) + ": every display parameter taken");
        }
        break;
      }
    }
  }
  const auto block = [&](const std::string& kind, const std::vector<std::string>& lines) {
    if (lines.empty()) return;
    const auto i = fe.take(kind);
    if (!i) {
      out.push_back("# " + name + ": every " + kind + " FE taken");
      return;
    }
    out.push_back(kind + "." + std::to_string(*i) + ":");
    out.insert(out.end(), lines.begin(), lines.end());
  };
  block("buttons", switches);
  block("indicators", indicators);
  block("display", parameters);
  return out;
}

}  // namespace

std::string wrap_words(const std::string& text, std::size_t width, const std::string& first_prefix,
                       const std::string& rest_prefix) {
  std::string out, line = first_prefix;
  std::size_t pos = 0;
  bool first = true;
  while (pos < text.size()) {
    auto end = text.find(' ', pos);
    if (end == std::string::npos) end = text.size();
    const std::string word = text.substr(pos, end - pos);
    pos = end + 1;
    if (word.empty()) continue;
    if (!first && line.size() + 1 + word.size() > width) {
      out += line + "\n";
      line = rest_prefix;
      first = true;
    }
    line += (first ? "" : " ") + word;
    first = false;
  }
  return out + line + "\n";
}

std::string describe_node(const sd::ScannedNode& n) {
  std::string out = "node " + hex(n.node.value(), 2) + "h: " + (n.family.family.empty() ? "unknown" : n.family.family);
  out += " (" + n.family.reason + ")";
  const auto& id = n.identity;
  std::string ident;
  if (id.device_type) ident += "device type " + hex(*id.device_type, 8) + "h";
  if (id.vendor_id) ident += std::string(ident.empty() ? "" : ", ") + "vendor " + hex(*id.vendor_id, 8) + "h";
  if (id.product_code) ident += std::string(ident.empty() ? "" : ", ") + "product " + hex(*id.product_code, 8) + "h";
  if (id.revision) ident += std::string(ident.empty() ? "" : ", ") + "revision " + hex(*id.revision, 8) + "h";
  if (id.serial) ident += std::string(ident.empty() ? "" : ", ") + "serial " + hex(*id.serial, 8) + "h";
  if (!ident.empty()) out += "; " + ident;
  if (!n.configured_as.empty()) {
    out += "; the gateway's sub-device " + n.configured_as + ", " + n.gateway_state;
    if (const auto s = state_text(n); !s.empty()) out += " (heartbeat: " + s + ")";
    return out;
  }
  if (!n.answered_sdo) out += "; heard but answered no SDO";
  if (const auto s = state_text(n); !s.empty()) out += "; " + s;
  return out;
}

std::string draft_mapping(const sd::ScanResult& scan, const DraftSettings& settings) {
  std::string subs, fes;
  FeCounters counters;
  std::size_t named = 0;
  for (const sd::ScannedNode& n : scan.nodes) {
    const std::string name = entry_name(n);
    const sd::DriverInfo* info = sd::find_driver_info(n.family.family);
    subs += "\n" + comment("  # ", describe_node(n));
    const HeartbeatChoice hb = heartbeat_choice(n);
    std::vector<std::string> entry = {name + ":", "  driver: " + n.family.family,
                                      "  node_id: 0x" + hex(n.node.value(), 2),
                                      "  heartbeat_ms: " + std::to_string(hb.ms) + "  # " + hb.why};
    std::string identity;
    if (n.identity.vendor_id) identity += "vendor_id: 0x" + hex(*n.identity.vendor_id, 8);
    if (n.identity.product_code)
      identity += std::string(identity.empty() ? "" : ", ") + "product_code: 0x" + hex(*n.identity.product_code, 8);
    if (!identity.empty())
      entry.push_back("  identity: { " + identity + " }  # checked at boot; revision and serial may be added");
    // Required options: a commissioning choice (a listing value exists: the driver's signals do
    // not depend on it) is the placeholder TODO, which `oegw check` refuses with how to find the
    // value (subdevices/driver_options.hpp kPlaceholder); a required option the signals depend on
    // (cia401's EDS) leaves the entry commented out.
    std::vector<std::string> options;
    std::string missing;
    if (info) {
      for (const sd::OptionSpec& o : info->options) {
        if (!o.required) continue;
        if (o.listing_value.empty()) {
          missing += (missing.empty() ? "" : ", ") + std::string(o.name);
          options.push_back("    " + std::string(o.name) + ": TODO");
          continue;
        }
        options.push_back("    # TODO required, a commissioning choice: " + std::string(o.description) + ".");
        options.push_back("    " + std::string(o.name) + ": " + std::string(sd::kPlaceholder) +
                          "  # `oegw check` refuses this until a value is written, and says how to find it");
      }
    }
    if (!options.empty()) {
      entry.push_back("  options:");
      entry.insert(entry.end(), options.begin(), options.end());
    }
    const bool active = info && missing.empty();
    if (!info) {
      subs += comment("  # ",
                      "TODO no driver fits this node; the entry below is left for reference (`oegw "
                      "signals` lists the drivers; a CiA 401 node may be driven by cia401 with its EDS).");
      entry[1] = "  driver: TODO";
    } else if (!active) {
      subs +=
          comment("  # ", "TODO " + n.family.family + " needs " + missing + ": uncomment the entry and fill it in " +
                              "(`oegw signals " + n.family.family + " --eds FILE` lists the signals an EDS gives).");
    }
    for (const auto& line : entry) subs += (active ? "  " : "  # ") + line + "\n";
    if (!active) continue;
    ++named;
    std::string error;
    const auto signals = sd::listing_signals(*info, {}, error);
    // "  # " marks a line to uncomment, "  ## " a note.
    fes += "\n  ## " + name + " (" + n.family.family + ", node " + hex(n.node.value(), 2) + "h)\n";
    if (!signals) {
      fes += "  ## (its signals depend on options: `oegw signals " + n.family.family + "`)\n";
      continue;
    }
    for (const auto& line : fe_lines(name, *signals, counters))
      fes += (line.rfind("# ", 0) == 0 ? "  #" : "  # ") + line + "\n";
  }

  std::string out;
  if (settings.through_gateway)
    out += "# DRAFT mapping file written by `oegw scan` through the gateway running on " + settings.downstream +
           "\n# (its sub-devices keep their names; their options are in its mapping file; format: "
           "docs/reference/mapping-file.md).\n";
  else
    out += "# DRAFT mapping file written by `oegw scan -i " + settings.downstream +
           "` (format: docs/reference/mapping-file.md).\n";
  out += "# Found " + std::to_string(scan.nodes.size()) + " node(s), " + std::to_string(named) +
         " with a driver entry. Review every TODO, then `oegw check FILE`.\n";
  out += "# Each driver's signals and options: `oegw signals DRIVER`.\n";
  if (scan.unconfigured) {
    out += "#\n";
    std::string text = "TODO a node without node-ID answered LSS (CiA 305 identify non-configured remote slave)";
    if (scan.unconfigured_address) {
      const auto& a = *scan.unconfigured_address;
      text += "; LSS fastscan read its address: vendor 0x" + hex(a.vendor, 8) + ", product 0x" + hex(a.product, 8) +
              ", revision 0x" + hex(a.revision, 8) + ", serial 0x" + hex(a.serial, 8);
      sd::NodeIdentity id{.vendor_id = a.vendor, .product_code = a.product};
      if (const auto f = sd::name_family(id); !f.family.empty()) text += " (" + f.family + ")";
    } else if (!scan.lss_note.empty()) {
      text += "; " + scan.lss_note;
    }
    text +=
        ". Give it a free node-ID with an LSS master (switch state selective to that address, configure node-ID, "
        "store configuration, switch state global waiting) and scan again; further nodes without node-ID "
        "show up only once this one has one.";
    out += comment("# ", text);
  }
  out += "\nupstream:                    # the gateway as a CiA 852 device on the host's bus\n";
  out += "  interface: " + settings.upstream + "  # TODO the host's bus (oegw scan --upstream)\n";
  out += "  node_id: 0x20              # TODO the gateway's node-ID on the host's bus\n";
  out += "  bitrate: " + std::to_string(settings.bitrate) + "\n";
  if (!settings.store.empty()) out += "  store: " + settings.store + "  # 1010h \"save\" (oegw scan --store)\n";
  out += "\ndownstream:                  # the bus scanned, the gateway is its master\n";
  out += "  interface: " + settings.downstream + "\n";
  out += "  bitrate: " + std::to_string(settings.bitrate) + "  # the scan does not measure it (oegw scan --bitrate)\n";
  out += "\nsubdevices:" + std::string(named == 0 ? " {}" : "") + "\n" + subs;
  out += "\n# Suggested functional elements for the signals of each node (uncomment what the cab uses;\n";
  out +=
      "# the FE kinds and fields: "
      "docs/reference/mapping-file.md#functional_elements-kindinstance-field-signal-required-may-be-empty).\n";
  out += "functional_elements: {}  # TODO remove the {} when you uncomment FE lines below\n" + fes;
  return out;
}

}  // namespace oegw::mapping
