#include "canopen/state.hpp"

#include <algorithm>
#include <charconv>
#include <iterator>
#include <limits>

namespace oegw::canopen {

namespace {

bool valid_key(std::string_view key) {
  if (key.empty() || key.front() == '.' || key.back() == '.' || key.find("..") != std::string_view::npos) return false;
  return std::all_of(key.begin(), key.end(),
                     [](char c) { return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' || c == '.'; });
}

int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

}  // namespace

// ---- writer -------------------------------------------------------------------------------

StateWriter::Scope::Scope(StateWriter& w, std::string_view name) : w_(w), length_(w.prefix_.size()) {
  if (!valid_key(name)) throw std::invalid_argument("StateWriter: bad scope name '" + std::string(name) + "'");
  w_.prefix_.append(name);
  w_.prefix_.push_back('.');
}

StateWriter::Scope::~Scope() { w_.prefix_.resize(length_); }

void StateWriter::begin_line(std::string_view key) {
  if (!valid_key(key)) throw std::invalid_argument("StateWriter: bad key '" + std::string(key) + "'");
  text_.append(prefix_);
  text_.append(key);
  text_.push_back(' ');
}

void StateWriter::put(std::string_view key, std::int64_t value) {
  begin_line(key);
  text_.append(std::to_string(value));
  text_.push_back('\n');
}

void StateWriter::put_bytes(std::string_view key, std::span<const std::uint8_t> bytes) {
  static constexpr char kHex[] = "0123456789abcdef";
  begin_line(key);
  text_.push_back('#');
  for (std::uint8_t b : bytes) {
    text_.push_back(kHex[b >> 4]);
    text_.push_back(kHex[b & 0x0F]);
  }
  text_.push_back('\n');
}

void StateWriter::put_text(std::string_view key, std::string_view text) {
  put_bytes(key, std::span(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
}

void StateWriter::put(std::string_view key, const CanFrame& frame) {
  const Scope s(*this, key);
  put("id", frame.id);
  put("rtr", frame.rtr);
  put("extended", frame.extended);
  // A remote frame's DLC is not its payload's length: kept apart.
  put("dlc", frame.dlc);
  put_bytes("data", frame.rtr ? std::span<const std::uint8_t>{} : frame.payload());
}

// ---- reader -------------------------------------------------------------------------------

StateReader StateReader::parse(std::string_view text) {
  StateReader r;
  r.text_ = std::make_shared<Text>();
  std::size_t line_no = 0;
  while (!text.empty()) {
    ++line_no;
    const std::size_t end = text.find('\n');
    const std::string_view line = text.substr(0, end);
    text = end == std::string_view::npos ? std::string_view{} : text.substr(end + 1);
    if (line.empty()) continue;
    const std::size_t space = line.find(' ');
    const std::string where = "state line " + std::to_string(line_no) + ": ";
    if (space == std::string_view::npos || space + 1 == line.size()) {
      throw StateError(where + "'" + std::string(line) + "' has no value");
    }
    const std::string_view key = line.substr(0, space);
    if (!valid_key(key)) throw StateError(where + "bad key '" + std::string(key) + "'");
    r.text_->entries.push_back(Entry{std::string(key), std::string(line.substr(space + 1)), line_no});
  }
  auto& e = r.text_->entries;
  std::stable_sort(e.begin(), e.end(), [](const Entry& a, const Entry& b) { return a.key < b.key; });
  const auto dup =
      std::adjacent_find(e.begin(), e.end(), [](const Entry& a, const Entry& b) { return a.key == b.key; });
  if (dup != e.end()) {
    throw StateError("state line " + std::to_string(std::next(dup)->line) + ": key '" + dup->key + "' appears twice");
  }
  return r;
}

StateReader StateReader::in(std::string_view name) const {
  if (!valid_key(name)) throw std::invalid_argument("StateReader: bad scope name '" + std::string(name) + "'");
  StateReader r = *this;
  r.prefix_.append(name);
  r.prefix_.push_back('.');
  return r;
}

StateReader::Entry* StateReader::find(std::string_view key) const {
  const std::string k = full(key);
  auto& e = text_->entries;
  const auto it =
      std::lower_bound(e.begin(), e.end(), k, [](const Entry& a, const std::string& b) { return a.key < b; });
  if (it == e.end() || it->key != k) return nullptr;
  return &*it;
}

bool StateReader::has(std::string_view key) const { return find(key) != nullptr; }

std::vector<std::string> StateReader::children() const {
  std::vector<std::string> out;
  auto& e = text_->entries;
  auto it =
      std::lower_bound(e.begin(), e.end(), prefix_, [](const Entry& a, const std::string& b) { return a.key < b; });
  for (; it != e.end() && std::string_view(it->key).starts_with(prefix_); ++it) {
    const std::string_view rest = std::string_view(it->key).substr(prefix_.size());
    std::string child(rest.substr(0, rest.find('.')));
    if (out.empty() || out.back() != child) out.push_back(std::move(child));
  }
  return out;
}

void StateReader::fail(std::string_view key, std::string_view what) const {
  throw StateError("state: '" + full(key) + "' " + std::string(what));
}

const std::string& StateReader::value(std::string_view key) const {
  Entry* e = find(key);
  if (e == nullptr) fail(key, "is missing");
  e->read = true;
  return e->value;
}

std::int64_t StateReader::integer(std::string_view key) const {
  const std::string& v = value(key);
  std::int64_t out = 0;
  const auto [end, ec] = std::from_chars(v.data(), v.data() + v.size(), out);
  if (ec != std::errc{} || end != v.data() + v.size()) fail(key, "is not an integer: '" + v + "'");
  return out;
}

std::int64_t StateReader::ranged(std::string_view key, std::int64_t min, std::int64_t max) const {
  const std::int64_t v = integer(key);
  if (v < min || v > max) {
    fail(key, "= " + std::to_string(v) + " is outside " + std::to_string(min) + ".." + std::to_string(max));
  }
  return v;
}

std::optional<TimePoint> StateReader::optional_time(std::string_view key) const {
  if (!has(key)) return std::nullopt;
  return time(key);
}

std::vector<std::uint8_t> StateReader::bytes(std::string_view key) const {
  const std::string& v = value(key);
  const auto bad = [&] { fail(key, "is not '#' and hex bytes: '" + v + "'"); };
  if (v.empty() || v.front() != '#' || (v.size() - 1) % 2 != 0) bad();
  std::vector<std::uint8_t> out;
  out.reserve((v.size() - 1) / 2);
  for (std::size_t i = 1; i < v.size(); i += 2) {
    const int hi = hex_digit(v[i]);
    const int lo = hex_digit(v[i + 1]);
    if (hi < 0 || lo < 0) bad();
    out.push_back(static_cast<std::uint8_t>(hi << 4 | lo));
  }
  return out;
}

std::string StateReader::text(std::string_view key, std::size_t max) const {
  const std::vector<std::uint8_t> b = bytes(key);
  if (b.size() > max) fail(key, "is longer than " + std::to_string(max) + " bytes");
  return std::string(b.begin(), b.end());
}

CanFrame StateReader::frame(std::string_view key) const {
  const StateReader r = in(key);
  const std::uint32_t id = r.get<std::uint32_t>("id");
  const bool extended = r.get<bool>("extended");
  if (id > (extended ? 0x1FFFFFFFu : 0x7FFu)) r.fail("id", "is too large");
  const std::uint8_t dlc = r.get<std::uint8_t>("dlc");
  if (dlc > 8) r.fail("dlc", "is above 8");
  const bool rtr = r.get<bool>("rtr");
  const std::vector<std::uint8_t> data = r.bytes("data");
  // A remote frame carries no data, whatever its DLC says (ISO 11898-1).
  if (data.size() != (rtr ? 0u : dlc)) r.fail("data", rtr ? "is not empty in a remote frame" : "is not dlc bytes long");
  CanFrame f = rtr ? CanFrame::remote(id, dlc) : CanFrame(id, data);
  f.extended = extended;
  return f;
}

NmtState StateReader::nmt_state(std::string_view key) const {
  const auto b = get<std::uint8_t>(key);
  if (!is_nmt_state(b)) fail(key, "= " + std::to_string(b) + " is no NMT state");
  return static_cast<NmtState>(b);
}

NodeId StateReader::node_id(std::string_view key) const {
  const NodeId id{get<std::uint8_t>(key)};
  if (!id.valid() && !id.unconfigured()) fail(key, "is no node-ID");
  return id;
}

std::vector<std::string> StateReader::unread() const {
  std::vector<std::string> out;
  for (const Entry& e : text_->entries) {
    if (!e.read) out.push_back(e.key);
  }
  return out;
}

}  // namespace oegw::canopen
