#include "canopen/309/ascii_gateway.hpp"

#include "canopen/305/lss.hpp"
#include "canopen/c_integer.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>

#include <fmt/format.h>

namespace oegw::canopen::ascii {

namespace {

struct TypeRow {
  DataType type;
  std::string_view name;
  std::size_t size;
};
constexpr std::array<TypeRow, 14> kTypes{{{DataType::B, "b", 1},
                                          {DataType::U8, "u8", 1},
                                          {DataType::U16, "u16", 2},
                                          {DataType::U32, "u32", 4},
                                          {DataType::U64, "u64", 8},
                                          {DataType::I8, "i8", 1},
                                          {DataType::I16, "i16", 2},
                                          {DataType::I32, "i32", 4},
                                          {DataType::I64, "i64", 8},
                                          {DataType::R32, "r32", 4},
                                          {DataType::R64, "r64", 8},
                                          {DataType::VS, "vs", 0},
                                          {DataType::OS, "os", 0},
                                          {DataType::D, "d", 0}}};

const TypeRow& row(DataType t) {
  return *std::find_if(kTypes.begin(), kTypes.end(), [t](const TypeRow& r) { return r.type == t; });
}

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

bool is_signed(DataType t) {
  return t == DataType::I8 || t == DataType::I16 || t == DataType::I32 || t == DataType::I64;
}
bool is_unsigned(DataType t) {
  return t == DataType::B || t == DataType::U8 || t == DataType::U16 || t == DataType::U32 || t == DataType::U64;
}

using Number = CInteger;
std::optional<Number> parse_number(std::string_view s) { return parse_c_integer(s); }

// An unsigned number in [lo, hi]; `what` names it for the message.
std::optional<std::uint64_t> parse_unsigned(std::string_view s, std::uint64_t lo, std::uint64_t hi, const char* what,
                                            std::string& error) {
  const auto n = parse_number(s);
  if (!n || n->negative) {
    error = fmt::format("'{}' is no {} (a number such as 5 or 0x1018)", s, what);
    return std::nullopt;
  }
  if (n->magnitude < lo || n->magnitude > hi) {
    error = fmt::format("{} {} is out of range ({}..{})", what, s, lo, hi);
    return std::nullopt;
  }
  return n->magnitude;
}

void put_le(std::vector<std::uint8_t>& out, std::uint64_t v, std::size_t size) {
  for (std::size_t i = 0; i < size; ++i) out.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}
std::uint64_t get_le(std::span<const std::uint8_t> b) {
  std::uint64_t v = 0;
  for (std::size_t i = 0; i < b.size(); ++i) v |= static_cast<std::uint64_t>(b[i]) << (8 * i);
  return v;
}

// The line in tokens: whitespace separates; a token opened by '"' runs to its closing quote
// ("" inside is one quote); '#' where a token would start ends the line (a comment).
struct Token {
  std::string text;
  bool quoted = false;
  std::size_t begin = 0;  // offset in the line (for the rest of a vs value)
};
bool tokenize(std::string_view line, std::vector<Token>& out, std::string& error) {
  std::size_t i = 0;
  while (i < line.size()) {
    if (std::isspace(static_cast<unsigned char>(line[i]))) {
      ++i;
      continue;
    }
    if (line[i] == '#') break;
    Token t;
    t.begin = i;
    if (line[i] == '"') {
      t.quoted = true;
      ++i;
      bool closed = false;
      while (i < line.size()) {
        if (line[i] == '"') {
          if (i + 1 < line.size() && line[i + 1] == '"') {
            t.text += '"';
            i += 2;
            continue;
          }
          ++i;
          closed = true;
          break;
        }
        t.text += line[i++];
      }
      if (!closed) {
        error = "a string opened with \" is not closed";
        return false;
      }
    } else {
      while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) t.text += line[i++];
    }
    out.push_back(std::move(t));
  }
  return true;
}

bool is_number_token(const Token& t) {
  return !t.quoted && !t.text.empty() && std::isdigit(static_cast<unsigned char>(t.text[0]));
}

}  // namespace

std::string_view to_string(GatewayError e) {
  switch (e) {
    case GatewayError::None: return "No error";
    case GatewayError::RequestNotSupported: return "Request not supported";
    case GatewayError::Syntax: return "Syntax error";
    case GatewayError::InternalState: return "Request not processed due to internal state";
    case GatewayError::Timeout: return "Time-out";
    case GatewayError::NoDefaultNet: return "No default net set";
    case GatewayError::NoDefaultNode: return "No default node set";
    case GatewayError::UnsupportedNet: return "Unsupported net";
    case GatewayError::UnsupportedNode: return "Unsupported node";
    case GatewayError::LssManufacturer: return "LSS implementation- / manufacturer-specific error";
    case GatewayError::LssNodeIdNotSupported: return "LSS node-ID not supported";
    case GatewayError::LssBitRateNotSupported: return "LSS bit-rate not supported";
    case GatewayError::LssStoreFailed: return "LSS parameter storing failed";
    case GatewayError::LssMediaError: return "LSS command failed because of media error";
  }
  return "Unknown error";
}

bool is_lss(Command c) {
  switch (c) {
    case Command::LssSwitchGlobal:
    case Command::LssSwitchSelective:
    case Command::LssSetNode:
    case Command::LssConfBitrate:
    case Command::LssActivateBitrate:
    case Command::LssStore:
    case Command::LssInquireAddress:
    case Command::LssGetNode:
    case Command::LssIdentNonConfigured:
    case Command::LssFastscan:
    case Command::LssIdentity:
    case Command::LssSlowscan: return true;
    default: return false;
  }
}

std::optional<DataType> parse_type(std::string_view name) {
  const std::string n = lower(name);
  for (const auto& r : kTypes)
    if (r.name == n) return r.type;
  return std::nullopt;
}
std::string_view to_string(DataType t) { return row(t).name; }
std::size_t size_of(DataType t) { return row(t).size; }
std::string type_names() {
  std::string out;
  for (const auto& r : kTypes) out += (out.empty() ? "" : ", ") + std::string(r.name);
  return out;
}

std::optional<std::vector<std::uint8_t>> encode(DataType t, std::string_view text, std::string& error) {
  std::vector<std::uint8_t> out;
  const std::size_t size = size_of(t);
  if (t == DataType::VS) return std::vector<std::uint8_t>(text.begin(), text.end());
  if (t == DataType::OS || t == DataType::D) {
    auto b = base64_decode(text);
    if (!b) error = fmt::format("'{}' is no MIME Base64 text (RFC 2045), as {} values are written", text, to_string(t));
    return b;
  }
  if (t == DataType::R32 || t == DataType::R64) {
    double v = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
    if (text.empty() || ec != std::errc{} || end != text.data() + text.size()) {
      error = fmt::format("'{}' is no {} value (a number such as 1.5 or -2e3)", text, to_string(t));
      return std::nullopt;
    }
    if (t == DataType::R32) {
      if (std::isfinite(v) && std::fabs(v) > std::numeric_limits<float>::max()) {
        error = fmt::format("{} is out of range for r32", text);
        return std::nullopt;
      }
      const auto f = static_cast<float>(v);
      std::uint32_t bits = 0;
      std::memcpy(&bits, &f, 4);
      put_le(out, bits, 4);
    } else {
      std::uint64_t bits = 0;
      std::memcpy(&bits, &v, 8);
      put_le(out, bits, 8);
    }
    return out;
  }
  const auto n = parse_number(text);
  if (!n) {
    error = fmt::format("'{}' is no {} value (a number such as 5, -5 or 0x1F)", text, to_string(t));
    return std::nullopt;
  }
  const unsigned bits = static_cast<unsigned>(size * 8);
  if (is_unsigned(t)) {
    const std::uint64_t max = t == DataType::B ? 1 : bits == 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << bits) - 1;
    if ((n->negative && n->magnitude != 0) || n->magnitude > max) {
      error = fmt::format("{} is out of range for {} (0..{})", text, to_string(t), max);
      return std::nullopt;
    }
    put_le(out, n->magnitude, size);
    return out;
  }
  // Signed: −2^(bits−1) .. 2^(bits−1)−1.
  const std::uint64_t max_pos = (std::uint64_t{1} << (bits - 1)) - 1;
  const std::uint64_t max_neg = std::uint64_t{1} << (bits - 1);
  if (n->negative ? n->magnitude > max_neg : n->magnitude > max_pos) {
    error = fmt::format("{} is out of range for {} (-{}..{})", text, to_string(t), max_neg, max_pos);
    return std::nullopt;
  }
  const std::uint64_t v = n->negative ? (~n->magnitude + 1) : n->magnitude;
  put_le(out, v, size);
  return out;
}

std::optional<std::string> format(DataType t, std::span<const std::uint8_t> b) {
  const std::size_t size = size_of(t);
  if (size != 0 && b.size() != size) return std::nullopt;
  switch (t) {
    case DataType::VS: {
      std::string s = "\"";
      for (const std::uint8_t c : b) {
        if (c == '"') s += '"';
        s += static_cast<char>(c);
      }
      return s + "\"";
    }
    case DataType::OS:
    case DataType::D: return base64_encode(b);
    case DataType::B: return std::to_string(b[0] != 0 ? 1 : 0);
    case DataType::R32: {
      float f = 0;
      const auto bits = static_cast<std::uint32_t>(get_le(b));
      std::memcpy(&f, &bits, 4);
      return fmt::format("{}", f);
    }
    case DataType::R64: {
      double d = 0;
      const std::uint64_t bits = get_le(b);
      std::memcpy(&d, &bits, 8);
      return fmt::format("{}", d);
    }
    default: break;
  }
  const std::uint64_t v = get_le(b);
  if (is_signed(t)) {
    const unsigned bits = static_cast<unsigned>(size * 8);
    const std::int64_t s = bits == 64 ? static_cast<std::int64_t>(v)
                                      : static_cast<std::int64_t>(v << (64 - bits)) >> (64 - bits);  // sign-extend
    return std::to_string(s);
  }
  return fmt::format("0x{:0{}X}", v, size * 2);
}

namespace {

constexpr std::string_view kLssCommands =
    "lss_switch_glob, lss_switch_sel, lss_set_node, lss_conf_bitrate, lss_activate_bitrate, lss_store, "
    "lss_inquire_addr, lss_get_node, lss_identity, lss_ident_nonconf, _lss_fastscan, _lss_slowscan";

Parsed error(GatewayError e, std::string message, std::optional<std::uint32_t> seq) {
  Parsed p;
  p.kind = Parsed::Kind::Error;
  p.error = e;
  p.message = std::move(message);
  p.request.sequence = seq;
  return p;
}

// One command line after its sequence and [[net] node] numbers: a handler per command word, each
// filling in the request (CiA 309-3 command forms, see the header) or answering what was wrong.
class LineParser {
 public:
  LineParser(const Defaults& defaults, std::optional<std::uint32_t> seq, std::vector<std::uint64_t> prefix,
             const Token& command, std::vector<Token> args)
      : defaults_(defaults),
        seq_(seq),
        prefix_(std::move(prefix)),
        cmd_(lower(command.text)),
        as_written_(command.text),
        args_(std::move(args)) {
    p_.kind = Parsed::Kind::Ok;
    p_.request.sequence = seq;
  }
  Parsed run();

 private:
  struct CommandRow {
    const char* word;
    Parsed (LineParser::*handle)();
  };
  struct LssRow {
    const char* word;
    Command command;
    const char* usage;
    Parsed (LineParser::*handle)(const char* usage);
  };
  static const CommandRow kCommands[];
  static const LssRow kLss[];

  Parsed fail(GatewayError e, std::string message) const { return error(e, std::move(message), seq_); }
  std::optional<Parsed> network_level(const char* what);
  std::optional<Parsed> node_level();
  std::optional<Parsed> index_sub();

  Parsed read();
  Parsed write();
  Parsed nmt();
  Parsed set();
  Parsed info();
  Parsed lss();

  std::optional<std::uint32_t> lss_u32(std::size_t i, std::uint64_t lo, std::uint64_t hi, const char* what) const;
  Parsed lss_bad(const char* usage) const { return fail(GatewayError::Syntax, fmt::format("expected {}", usage)); }
  Parsed lss_not_32_bit(std::size_t i, const char* usage) const {
    return fail(GatewayError::Syntax, fmt::format("'{}' is no 32-bit number; expected {}", args_[i].text, usage));
  }
  Parsed lss_no_args(const char* usage);
  Parsed lss_switch_global(const char* usage);
  Parsed lss_switch_selective(const char* usage);
  Parsed lss_set_node(const char* usage);
  Parsed lss_conf_bitrate(const char* usage);
  Parsed lss_activate_bitrate(const char* usage);
  Parsed lss_inquire_address(const char* usage);
  Parsed lss_fastscan(const char* usage);
  Parsed lss_range(const char* usage);

  const Defaults& defaults_;
  std::optional<std::uint32_t> seq_;
  std::vector<std::uint64_t> prefix_;
  std::string cmd_;         // the command word, lower case
  std::string as_written_;  // the command word as the line has it (for the messages)
  std::vector<Token> args_;
  Parsed p_;
};

const LineParser::CommandRow LineParser::kCommands[] =
    {{"r", &LineParser::read},      {"read", &LineParser::read},          {"w", &LineParser::write},
     {"write", &LineParser::write}, {"start", &LineParser::nmt},          {"stop", &LineParser::nmt},
     {"preop", &LineParser::nmt},   {"preoperational", &LineParser::nmt}, {"reset", &LineParser::nmt},
     {"set", &LineParser::set},     {"info", &LineParser::info}};

// CiA 309-3 LSS commands: `[net] lss_...`, the network only (CANopenNode's and lely's syntax).
const LineParser::LssRow LineParser::kLss[] =
    {{"lss_switch_glob", Command::LssSwitchGlobal, "lss_switch_glob 0|1 (0 waiting, 1 configuration)",
      &LineParser::lss_switch_global},
     {"lss_switch_sel", Command::LssSwitchSelective, "lss_switch_sel <vendor-ID> <product code> <revision> <serial>",
      &LineParser::lss_switch_selective},
     {"lss_set_node", Command::LssSetNode, "lss_set_node <node-ID 1..127, or 255: none>", &LineParser::lss_set_node},
     {"lss_conf_bitrate", Command::LssConfBitrate,
      "lss_conf_bitrate 0 <table index: 0 1000, 1 800, 2 500, 3 250, 4 125, 6 50, 7 20, 8 10 kbit/s>",
      &LineParser::lss_conf_bitrate},
     {"lss_activate_bitrate", Command::LssActivateBitrate, "lss_activate_bitrate <switch delay in ms, 0..65535>",
      &LineParser::lss_activate_bitrate},
     {"lss_store", Command::LssStore, "lss_store", &LineParser::lss_no_args},
     {"lss_inquire_addr", Command::LssInquireAddress,
      "lss_inquire_addr [<part: 0..3 or 0x5A..0x5D (vendor, product, revision, serial)>]",
      &LineParser::lss_inquire_address},
     {"lss_get_node", Command::LssGetNode, "lss_get_node", &LineParser::lss_no_args},
     {"lss_ident_nonconf", Command::LssIdentNonConfigured, "lss_ident_nonconf", &LineParser::lss_no_args},
     {"_lss_fastscan", Command::LssFastscan,
      "_lss_fastscan [<step time-out in ms, 1..65535>], or lely's _lss_fastscan <vendor-ID> <mask> <product "
      "code> <mask> <revision> <mask> <serial> <mask> (a mask's 1 bits are known)",
      &LineParser::lss_fastscan},
     {"lss_identity", Command::LssIdentity,
      "lss_identity <vendor-ID> <product code> <revision low> <revision high> <serial low> <serial high>",
      &LineParser::lss_range},
     {"_lss_slowscan", Command::LssSlowscan,
      "_lss_slowscan <vendor-ID> <product code> <revision low> <revision high> <serial low> <serial high>",
      &LineParser::lss_range}};

Parsed LineParser::run() {
  const auto* row =
      std::find_if(std::begin(kCommands), std::end(kCommands), [&](const CommandRow& c) { return cmd_ == c.word; });
  if (row != std::end(kCommands)) return (this->*row->handle)();
  if (cmd_.starts_with("lss_") || cmd_.starts_with("_lss_")) return lss();
  return fail(
      GatewayError::RequestNotSupported,
      fmt::format("no command '{}'; this gateway has r[ead], w[rite], start, stop, preop[erational], reset node, "
                  "reset comm[unication], set network, set node, set sdo_timeout, info version, {}",
                  as_written_, kLssCommands));
}

// The network of a network-level command ([net] set node, [net] set sdo_timeout).
std::optional<Parsed> LineParser::network_level(const char* what) {
  if (prefix_.size() > 1)
    return fail(GatewayError::Syntax, fmt::format("'{}' takes a network number only, not a node", what));
  if (prefix_.size() == 1) {
    if (prefix_[0] < 1 || prefix_[0] > 127)
      return fail(GatewayError::UnsupportedNet, fmt::format("network {} (1..127)", prefix_[0]));
    p_.request.network = static_cast<std::uint16_t>(prefix_[0]);
  } else if (defaults_.network) {
    p_.request.network = *defaults_.network;
  } else {
    return fail(GatewayError::NoDefaultNet, "give the network before the command or `set network N` first");
  }
  return std::nullopt;
}

// The network and node of a node-level command ([[net] node] r/w/NMT).
std::optional<Parsed> LineParser::node_level() {
  std::optional<std::uint64_t> net, node;
  if (prefix_.size() == 2) {
    net = prefix_[0];
    node = prefix_[1];
  } else if (prefix_.size() == 1) {
    node = prefix_[0];
  }
  if (!net && defaults_.network) net = *defaults_.network;
  if (!node && defaults_.node) node = *defaults_.node;
  if (!net)
    return fail(GatewayError::NoDefaultNet, "give the network and node before the command or `set network N` first");
  if (!node) return fail(GatewayError::NoDefaultNode, "give the node before the command or `set node N` first");
  if (*net < 1 || *net > 127) return fail(GatewayError::UnsupportedNet, fmt::format("network {} (1..127)", *net));
  if (*node < 1 || *node > 127) return fail(GatewayError::UnsupportedNode, fmt::format("node {} (1..127)", *node));
  p_.request.network = static_cast<std::uint16_t>(*net);
  p_.request.node = static_cast<std::uint8_t>(*node);
  return std::nullopt;
}

// <index> <sub-index> <data type>, the first three arguments of r and w.
std::optional<Parsed> LineParser::index_sub() {
  std::string e;
  const auto index = parse_unsigned(args_[0].text, 0, 0xFFFF, "index", e);
  if (!index) return fail(GatewayError::Syntax, e);
  const auto sub = parse_unsigned(args_[1].text, 0, 0xFF, "sub-index", e);
  if (!sub) return fail(GatewayError::Syntax, e);
  p_.request.index = static_cast<std::uint16_t>(*index);
  p_.request.sub = static_cast<std::uint8_t>(*sub);
  const auto type = parse_type(args_[2].text);
  if (!type)
    return fail(GatewayError::Syntax, fmt::format("'{}' is no data type; one of {}", args_[2].text, type_names()));
  p_.request.type = *type;
  return std::nullopt;
}

Parsed LineParser::read() {
  p_.request.command = Command::Read;
  if (auto e = node_level()) return *e;
  if (args_.size() != 3) return fail(GatewayError::Syntax, "expected r[ead] <index> <sub-index> <data type>");
  if (auto e = index_sub()) return *e;
  return p_;
}

Parsed LineParser::write() {
  Request& r = p_.request;
  r.command = Command::Write;
  if (auto e = node_level()) return *e;
  if (args_.size() < 4) return fail(GatewayError::Syntax, "expected w[rite] <index> <sub-index> <data type> <value>");
  if (auto e = index_sub()) return *e;
  std::string value;
  if (r.type == DataType::VS && args_[3].quoted) {
    if (args_.size() != 4) return fail(GatewayError::Syntax, "text after the quoted vs value");
    value = args_[3].text;
  } else if (r.type == DataType::VS) {
    // Unquoted words are one string, joined by single spaces; quote it to keep spaces.
    for (std::size_t i = 3; i < args_.size(); ++i) {
      if (args_[i].quoted) return fail(GatewayError::Syntax, "a vs value is one quoted string or unquoted words");
      value += (i == 3 ? "" : " ") + args_[i].text;
    }
  } else {
    if (args_.size() != 4)
      return fail(GatewayError::Syntax,
                  fmt::format("a {} value is one token; text follows '{}'", to_string(r.type), args_[3].text));
    value = args_[3].text;
  }
  std::string e;
  auto data = encode(r.type, value, e);
  if (!data) return fail(GatewayError::Syntax, e);
  r.data = std::move(*data);
  return p_;
}

// start, stop, preop[erational], reset node, reset comm[unication].
Parsed LineParser::nmt() {
  const struct {
    const char* word;
    const char* second;  // nullptr: none
    Command command;
  } nmt[] = {{"start", nullptr, Command::Start},
             {"stop", nullptr, Command::Stop},
             {"preop", nullptr, Command::PreOperational},
             {"preoperational", nullptr, Command::PreOperational},
             {"reset", "node", Command::ResetNode},
             {"reset", "comm", Command::ResetCommunication},
             {"reset", "communication", Command::ResetCommunication}};
  for (const auto& n : nmt) {
    if (cmd_ != n.word) continue;
    if (n.second != nullptr && (args_.empty() || lower(args_[0].text) != n.second)) continue;
    p_.request.command = n.command;
    if (!prefix_.empty() && prefix_.back() == 0)
      return fail(GatewayError::RequestNotSupported, "node 0 (all nodes): name each node");
    if (auto e = node_level()) return *e;
    if (args_.size() != (n.second != nullptr ? 1u : 0u))
      return fail(GatewayError::Syntax, fmt::format("text after '{}'", cmd_));
    return p_;
  }
  return fail(GatewayError::Syntax, "expected `reset node` or `reset comm[unication]`");
}

// set network|node|sdo_timeout <value>.
Parsed LineParser::set() {
  Request& r = p_.request;
  if (args_.empty()) return fail(GatewayError::Syntax, "expected set network|node|sdo_timeout <value>");
  const std::string what = lower(args_[0].text);
  if (args_.size() != 2) return fail(GatewayError::Syntax, fmt::format("expected set {} <value>", what));
  std::string e;
  if (what == "network") {
    r.command = Command::SetNetwork;
    if (!prefix_.empty()) return fail(GatewayError::Syntax, "`set network` takes no network or node before it");
    const auto v = parse_unsigned(args_[1].text, 1, 127, "network", e);
    if (!v) return fail(GatewayError::Syntax, e);
    r.value = static_cast<std::uint32_t>(*v);
    return p_;
  }
  if (what == "node") {
    r.command = Command::SetNode;
    if (auto err = network_level("set node")) return *err;
    const auto v = parse_unsigned(args_[1].text, 1, 127, "node", e);
    if (!v) return fail(GatewayError::Syntax, e);
    r.value = static_cast<std::uint32_t>(*v);
    return p_;
  }
  if (what == "sdo_timeout") {
    r.command = Command::SetSdoTimeout;
    if (auto err = network_level("set sdo_timeout")) return *err;
    const auto v = parse_unsigned(args_[1].text, 1, 0xFFFF, "SDO time-out in ms", e);
    if (!v) return fail(GatewayError::Syntax, e);
    r.value = static_cast<std::uint32_t>(*v);
    return p_;
  }
  return fail(GatewayError::RequestNotSupported,
              fmt::format("`set {}`; this gateway has set network, set node, set sdo_timeout", what));
}

Parsed LineParser::info() {
  p_.request.command = Command::InfoVersion;
  if (args_.size() != 1 || lower(args_[0].text) != "version")
    return fail(GatewayError::RequestNotSupported, "`info` has `info version` only");
  if (!prefix_.empty()) return fail(GatewayError::Syntax, "`info version` takes no network or node before it");
  return p_;
}

Parsed LineParser::lss() {
  const auto* row = std::find_if(std::begin(kLss), std::end(kLss), [&](const LssRow& t) { return cmd_ == t.word; });
  if (row == std::end(kLss))
    return fail(GatewayError::RequestNotSupported,
                fmt::format("no command '{}'; this gateway's LSS commands are {}", as_written_, kLssCommands));
  p_.request.command = row->command;
  if (auto e = network_level(row->word)) return *e;
  return (this->*row->handle)(row->usage);
}

std::optional<std::uint32_t> LineParser::lss_u32(std::size_t i, std::uint64_t lo, std::uint64_t hi,
                                                 const char* what) const {
  std::string e;
  const auto v = parse_unsigned(args_[i].text, lo, hi, what, e);
  if (!v) return std::nullopt;
  return static_cast<std::uint32_t>(*v);
}

// lss_store, lss_get_node, lss_ident_nonconf.
Parsed LineParser::lss_no_args(const char* usage) {
  if (!args_.empty()) return lss_bad(usage);
  return p_;
}

Parsed LineParser::lss_switch_global(const char* usage) {
  if (args_.size() != 1) return lss_bad(usage);
  const auto v = lss_u32(0, 0, 1, "mode");
  if (!v) return lss_bad(usage);
  p_.request.value = *v;
  return p_;
}

Parsed LineParser::lss_switch_selective(const char* usage) {
  if (args_.size() != 4) return lss_bad(usage);
  for (std::size_t i = 0; i < 4; ++i) {
    const auto v = lss_u32(i, 0, 0xFFFFFFFF, "LSS address part");
    if (!v) return lss_not_32_bit(i, usage);
    p_.request.address[i] = *v;
  }
  return p_;
}

Parsed LineParser::lss_set_node(const char* usage) {
  if (args_.size() != 1) return lss_bad(usage);
  const auto v = lss_u32(0, 1, 255, "node-ID");
  if (!v || (*v > 127 && *v != 255))
    return fail(GatewayError::Syntax, fmt::format("node-ID '{}': 1..127, or 255 (none)", args_[0].text));
  p_.request.value = *v;
  return p_;
}

Parsed LineParser::lss_conf_bitrate(const char* usage) {
  if (args_.size() != 2) return lss_bad(usage);
  const auto table_selector = lss_u32(0, 0, 0xFF, "table selector");
  if (!table_selector) return lss_bad(usage);
  if (*table_selector != 0)
    return fail(GatewayError::LssBitRateNotSupported,
                fmt::format("table selector {}: only 0, the CiA 305 standard table", *table_selector));
  const auto index = lss_u32(1, 0, 0xFF, "table index");
  if (!index) return lss_bad(usage);
  if (!lss::standard_bit_rate_kbit(static_cast<std::uint8_t>(*index)))
    return fail(GatewayError::LssBitRateNotSupported,
                fmt::format("table index {} is not in the CiA 305 table (0 1000, 1 800, 2 500, 3 250, 4 125, "
                            "6 50, 7 20, 8 10 kbit/s)",
                            *index));
  p_.request.value = *index;
  return p_;
}

Parsed LineParser::lss_activate_bitrate(const char* usage) {
  if (args_.size() != 1) return lss_bad(usage);
  const auto v = lss_u32(0, 0, 0xFFFF, "switch delay");
  if (!v) return lss_bad(usage);
  p_.request.value = *v;
  return p_;
}

Parsed LineParser::lss_inquire_address(const char* usage) {
  if (args_.empty()) return p_;
  if (args_.size() != 1) return lss_bad(usage);
  const auto v = lss_u32(0, 0, 0xFF, "part");
  if (v && *v <= 3) p_.request.lss_part = static_cast<std::uint8_t>(*v);
  else if (v && *v >= lss::cs::kInquireVendor && *v <= lss::cs::kInquireSerial)
    p_.request.lss_part = static_cast<std::uint8_t>(*v - lss::cs::kInquireVendor);
  else return lss_bad(usage);
  return p_;
}

Parsed LineParser::lss_fastscan(const char* usage) {
  Request& r = p_.request;
  if (args_.empty()) return p_;
  if (args_.size() == 8) {  // lely's form: value and mask of each part
    std::array<std::uint32_t, 4> mask{};
    for (std::size_t i = 0; i < 8; ++i) {
      const auto v = lss_u32(i, 0, 0xFFFFFFFF, "LSS address part");
      if (!v) return lss_not_32_bit(i, usage);
      (i % 2 == 0 ? r.address[i / 2] : mask[i / 2]) = *v;
    }
    r.known_mask = mask;
    return p_;
  }
  if (args_.size() != 1) return lss_bad(usage);
  const auto v = lss_u32(0, 1, 0xFFFF, "time-out");
  if (!v) return lss_bad(usage);
  r.value = *v;
  return p_;
}

// lss_identity, _lss_slowscan: vendor, product, revision low..high, serial low..high.
Parsed LineParser::lss_range(const char* usage) {
  Request& r = p_.request;
  if (args_.size() != 6) return lss_bad(usage);
  for (std::size_t i = 0; i < 6; ++i) {
    const auto v = lss_u32(i, 0, 0xFFFFFFFF, "LSS address part");
    if (!v) return lss_not_32_bit(i, usage);
    r.range[i] = *v;
  }
  if (r.range[2] > r.range[3] || r.range[4] > r.range[5])
    return fail(GatewayError::Syntax, "a range's low end above its high end (revision low..high, serial low..high)");
  return p_;
}

}  // namespace

Parsed parse(std::string_view line, const Defaults& defaults) {
  std::vector<Token> tokens;
  std::string why;
  // The sequence first, so that even a line that fails later is answered with it.
  std::optional<std::uint32_t> seq;
  {
    std::size_t i = 0;
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    if (i < line.size() && line[i] == '[') {
      const std::size_t close = line.find(']', i);
      if (close == std::string_view::npos)
        return error(GatewayError::Syntax, "'[' opens a sequence number but no ']' closes it", {});
      std::string e;
      const auto n = parse_unsigned(line.substr(i + 1, close - i - 1), 0, 0xFFFFFFFF, "sequence number", e);
      if (!n) return error(GatewayError::Syntax, e, {});
      seq = static_cast<std::uint32_t>(*n);
      line = line.substr(close + 1);
    }
  }
  if (!tokenize(line, tokens, why)) return error(GatewayError::Syntax, why, seq);
  if (tokens.empty()) {
    if (seq) return error(GatewayError::Syntax, "a sequence number and no command", seq);
    Parsed p;
    return p;
  }
  // [[net] node]: up to two numbers before the command.
  std::vector<std::uint64_t> prefix;
  std::size_t k = 0;
  for (; k < tokens.size() && is_number_token(tokens[k]); ++k) {
    if (prefix.size() == 2)
      return error(GatewayError::Syntax, "more than two numbers (network and node) before the command", seq);
    const auto n = parse_number(tokens[k].text);
    if (!n || n->negative || n->magnitude > 0xFFFF)
      return error(GatewayError::Syntax, fmt::format("'{}' is no network or node number", tokens[k].text), seq);
    prefix.push_back(n->magnitude);
  }
  if (k == tokens.size()) return error(GatewayError::Syntax, "no command after the network and node numbers", seq);
  return LineParser(defaults, seq, std::move(prefix), tokens[k],
                    std::vector<Token>(tokens.begin() + static_cast<std::ptrdiff_t>(k) + 1, tokens.end()))
      .run();
}

std::string answer_ok(std::uint32_t seq) { return fmt::format("[{}] OK", seq); }
std::string answer_value(std::uint32_t seq, const std::string& value) { return fmt::format("[{}] {}", seq, value); }
std::string answer_abort(std::uint32_t seq, SdoAbortCode code) {
  return fmt::format("[{}] ERROR: {:08X} ({})", seq, static_cast<std::uint32_t>(code), to_string(code));
}
std::string answer_error(std::uint32_t seq, GatewayError e, const std::string& detail) {
  return fmt::format("[{}] ERROR: {} ({}{}{})", seq, static_cast<int>(e), to_string(e), detail.empty() ? "" : ": ",
                     detail);
}

std::string boot_up_event(std::uint16_t network, std::uint8_t node) {
  return fmt::format("{} {} BOOT_UP", network, node);
}
std::string emcy_event(std::uint16_t network, std::uint8_t node, std::uint16_t code, std::uint8_t error_register,
                       std::span<const std::uint8_t, 5> m) {
  return fmt::format("{} {} EMCY {:04X} {:02X} {} {} {} {} {}", network, node, code, error_register, m[0], m[1], m[2],
                     m[3], m[4]);
}

namespace {
constexpr std::string_view kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
}

std::string base64_encode(std::span<const std::uint8_t> b) {
  std::string out;
  for (std::size_t i = 0; i < b.size(); i += 3) {
    const std::size_t n = std::min<std::size_t>(3, b.size() - i);
    std::uint32_t v = static_cast<std::uint32_t>(b[i]) << 16;
    if (n > 1) v |= static_cast<std::uint32_t>(b[i + 1]) << 8;
    if (n > 2) v |= b[i + 2];
    for (std::size_t k = 0; k < 4; ++k) out += k <= n ? kAlphabet[(v >> (18 - 6 * k)) & 0x3F] : '=';
  }
  return out;
}

std::optional<std::vector<std::uint8_t>> base64_decode(std::string_view t) {
  if (t.size() % 4 != 0) return std::nullopt;
  std::vector<std::uint8_t> out;
  for (std::size_t i = 0; i < t.size(); i += 4) {
    std::uint32_t v = 0;
    std::size_t pad = 0;
    for (std::size_t k = 0; k < 4; ++k) {
      const char c = t[i + k];
      if (c == '=' && i + 4 == t.size() && k >= 2) {
        ++pad;
        v <<= 6;
        continue;
      }
      const auto pos = kAlphabet.find(c);
      if (pos == std::string_view::npos || pad != 0) return std::nullopt;
      v = (v << 6) | static_cast<std::uint32_t>(pos);
    }
    out.push_back(static_cast<std::uint8_t>(v >> 16));
    if (pad < 2) out.push_back(static_cast<std::uint8_t>(v >> 8));
    if (pad < 1) out.push_back(static_cast<std::uint8_t>(v));
  }
  return out;
}

}  // namespace oegw::canopen::ascii
