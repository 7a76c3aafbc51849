#include "canopen/306/eds_reader.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstring>
#include <sstream>

#include "canopen/c_integer.hpp"
#include "canopen/text_file.hpp"

namespace oegw::canopen::eds {

using canopen::Access;
using canopen::DataType;
using canopen::ObjectCode;

namespace {

constexpr std::string_view kLists[] = {"MandatoryObjects", "OptionalObjects", "ManufacturerObjects"};

std::string trim(std::string_view s) {
  std::size_t b = 0;
  std::size_t e = s.size();
  while (b < e && (s[b] == ' ' || s[b] == '\t' || s[b] == '\r' || s[b] == '\n')) ++b;
  while (e > b && (s[e - 1] == ' ' || s[e - 1] == '\t' || s[e - 1] == '\r' || s[e - 1] == '\n')) --e;
  return std::string(s.substr(b, e - b));
}

std::string upper(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return out;
}

bool iequals(std::string_view a, std::string_view b) { return upper(a) == upper(b); }

// Printable form of untrusted text for messages: at most 40 characters, control bytes escaped.
std::string quote(std::string_view s) {
  std::string out = "'";
  for (std::size_t i = 0; i < s.size() && i < 40; ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c < 0x20 || c >= 0x7F) {
      static constexpr char kHex[] = "0123456789abcdef";
      out += "\\x";
      out += kHex[c >> 4];
      out += kHex[c & 0xF];
    } else {
      out += static_cast<char>(c);
    }
  }
  if (s.size() > 40) out += "...";
  return out + "'";
}

std::string hex(std::uint64_t v, int width) {
  std::ostringstream os;
  os << std::uppercase << std::hex;
  os.width(width);
  os.fill('0');
  os << v;
  return os.str();
}

// CiA 306 §4.5.3: decimal, 0x hexadecimal, or octal with a leading 0; an optional '-' sign
// (two's complement in 64 bits).
bool parse_integer(std::string_view s, std::uint64_t& out) {
  const auto n = parse_c_integer(s);
  if (!n || (n->negative && n->magnitude > (std::uint64_t{1} << 63))) return false;
  out = n->negative ? ~n->magnitude + 1 : n->magnitude;
  return true;
}

bool parse_real(std::string_view s, double& out) {
  const std::string t(s);
  if (t.empty()) return false;
  char* end = nullptr;
  out = std::strtod(t.c_str(), &end);
  return end == t.c_str() + t.size();
}

// A numeric value, possibly with $NODEID ("$NODEID+0x180", "0x180+$NODEID", "$NODEID").
bool parse_value_number(const std::string& text, Value& v) {
  v = Value{};
  v.text = text;
  std::string rest = text;
  const std::string u = upper(text);
  const auto pos = u.find("$NODEID");
  if (pos != std::string::npos) {
    v.node_relative = true;
    rest = trim(text.substr(0, pos)) + "\x01" + trim(text.substr(pos + 7));
    if (rest == "\x01") {
      rest.clear();
    } else if (rest.rfind("\x01+", 0) == 0) {
      rest = trim(rest.substr(2));
    } else if (rest.size() >= 2 && rest.compare(rest.size() - 2, 2, "+\x01") == 0) {
      rest = trim(rest.substr(0, rest.size() - 2));
    } else {
      return false;
    }
    if (upper(rest).find("$NODEID") != std::string::npos) return false;
    if (rest.empty()) {
      v.numeric = true;
      return true;
    }
  }
  if (!parse_integer(rest, v.number)) return false;
  v.numeric = true;
  return true;
}

bool is_known_type(std::uint64_t t) {
  switch (static_cast<DataType>(t)) {
    case DataType::Boolean:
    case DataType::Integer8:
    case DataType::Integer16:
    case DataType::Integer32:
    case DataType::Unsigned8:
    case DataType::Unsigned16:
    case DataType::Unsigned32:
    case DataType::Real32:
    case DataType::VisibleString:
    case DataType::OctetString:
    case DataType::UnicodeString:
    case DataType::TimeOfDay:
    case DataType::TimeDifference:
    case DataType::Domain:
    case DataType::Integer24:
    case DataType::Real64:
    case DataType::Integer40:
    case DataType::Integer48:
    case DataType::Integer56:
    case DataType::Integer64:
    case DataType::Unsigned24:
    case DataType::Unsigned40:
    case DataType::Unsigned48:
    case DataType::Unsigned56:
    case DataType::Unsigned64: return t <= 0xFFFF;
  }
  return false;
}

bool is_integer(DataType t) { return canopen::is_signed_integer(t) || canopen::is_unsigned_integer(t); }

// Does `v` (two's complement) fit the integer type `t`?
bool fits(DataType t, std::uint64_t v) {
  const std::size_t n = canopen::fixed_size(t);
  if (t == DataType::Boolean) return v <= 1;
  if (n == 0 || n >= 8) return true;
  const unsigned bits = static_cast<unsigned>(n * 8);
  if (canopen::is_signed_integer(t)) {
    const auto s = static_cast<std::int64_t>(v);
    const std::int64_t lo = -(std::int64_t{1} << (bits - 1));
    const std::int64_t hi = (std::int64_t{1} << (bits - 1)) - 1;
    return s >= lo && s <= hi;
  }
  return v < (std::uint64_t{1} << bits);
}

std::optional<Access> parse_access(std::string_view s) {
  const std::string u = upper(trim(s));
  if (u == "RO") return Access::ReadOnly;
  if (u == "WO") return Access::WriteOnly;
  if (u == "RW") return Access::ReadWrite;
  if (u == "RWR") return Access::ReadWriteRead;
  if (u == "RWW") return Access::ReadWriteWrite;
  if (u == "CONST") return Access::Const;
  return std::nullopt;
}

// ---- the INI layer -------------------------------------------------------------------------

struct Key {
  std::string name;  // as written
  std::string value;
  int line = 0;
};

struct Section {
  std::string name;  // as written
  int line = 0;
  std::vector<Key> keys;
  [[nodiscard]] const Key* get(std::string_view key) const {
    for (const auto& k : keys)
      if (iequals(k.name, key)) return &k;
    return nullptr;
  }
};

class Parser {
 public:
  Parser(std::string_view name, std::string& error) : name_(name), error_(error) {}

  std::optional<File> run(std::string_view text);

 private:
  bool fail(int line, const std::string& what) {
    error_ = name_ + ":" + std::to_string(line) + ": " + what;
    return false;
  }
  void warn(int line, const std::string& what) {
    warnings_.push_back(name_ + ":" + std::to_string(line) + ": warning: " + what);
  }
  bool tokenize(std::string_view text);
  bool read_lists(File& file);
  bool read_object(File& file, std::uint16_t index, const std::string& list, int list_line);
  bool read_entry(const Section& s, SubEntry& e, bool var_in_object, bool domain = false);
  bool read_compact(const Section& s, ObjectEntry& o, std::uint64_t count);
  bool read_value(const Section& s, const Key& k, DataType type, std::optional<Value>& out, bool is_limit);
  [[nodiscard]] const Section* find_section(std::string_view name) const {
    for (const auto& s : sections_)
      if (iequals(s.name, name)) return &s;
    return nullptr;
  }

  std::string name_;
  std::string& error_;
  std::vector<Section> sections_;
  std::vector<std::string> warnings_;
  int last_line_ = 0;
  // Object sections -> position in sections_, keyed index << 9 | (sub + 1) ([1A00subN]) or
  // index << 9 ([1A00]); see object_key().
  std::map<std::uint32_t, std::size_t> object_sections_;
};

// Section names "1A00" or "1A00sub3" (hex, case-insensitive) -> key; nullopt for other names.
std::optional<std::uint32_t> object_key(std::string_view name) {
  const std::string u = upper(name);
  const auto sub_pos = u.find("SUB");
  const std::string idx = u.substr(0, sub_pos);
  if (idx.empty() || idx.size() > 4) return std::nullopt;
  for (char c : idx)
    if (!std::isxdigit(static_cast<unsigned char>(c))) return std::nullopt;
  std::uint32_t index = 0;
  std::from_chars(idx.data(), idx.data() + idx.size(), index, 16);
  std::uint32_t sub_key = 0;
  if (sub_pos != std::string::npos) {
    const std::string sub = u.substr(sub_pos + 3);
    if (sub.empty() || sub.size() > 2) return std::nullopt;
    for (char c : sub)
      if (!std::isxdigit(static_cast<unsigned char>(c))) return std::nullopt;
    std::uint32_t s = 0;
    std::from_chars(sub.data(), sub.data() + sub.size(), s, 16);
    sub_key = s + 1;
  }
  return index << 9 | sub_key;
}

bool Parser::tokenize(std::string_view text) {
  int line_no = 0;
  std::size_t pos = 0;
  Section* current = nullptr;
  if (text.substr(0, 3) == "\xEF\xBB\xBF") pos = 3;  // UTF-8 byte-order mark
  // CiA 306 writes the EDS as an INI text file: a control byte (a NUL, an escape, ...) means
  // a binary file given for an EDS, said in one short line rather than as the escaped bytes of
  // its first "line". Tab, line ends, form feed and the DOS end-of-file mark 1Ah are text; bytes
  // 80h..FFh are too (vendors write their names in Windows-1252).
  for (std::size_t i = pos; i < text.size(); ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if ((c < 0x20 && c != '\t' && c != '\n' && c != '\r' && c != '\v' && c != '\f' && c != 0x1A) || c == 0x7F) {
      static constexpr char kHex[] = "0123456789ABCDEF";
      const auto line = 1 + std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(i), '\n');
      return fail(static_cast<int>(line), std::string("not a text file (byte 0x") + kHex[c >> 4] + kHex[c & 0xF] +
                                              " at offset " + std::to_string(i) +
                                              "); expected an EDS, a text file (CiA 306)");
    }
  }
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    const std::string line = trim(text.substr(pos, end - pos));
    pos = end + 1;
    ++line_no;
    last_line_ = line_no;
    if (line.empty() || line[0] == ';' || line[0] == '#') continue;
    if (line[0] == '[') {
      if (line.back() != ']') return fail(line_no, "expected ']' closing the section name in " + quote(line));
      const std::string sname = trim(line.substr(1, line.size() - 2));
      if (sname.empty()) return fail(line_no, "expected a section name between '[' and ']'");
      if (sname.find_first_of("[]") != std::string::npos)
        return fail(line_no, "expected one section name in " + quote(line));
      if (const Section* prev = find_section(sname); prev != nullptr)
        return fail(line_no, "duplicate section [" + sname + "] (first at line " + std::to_string(prev->line) + ")");
      if (auto key = object_key(sname)) {
        if (auto it = object_sections_.find(*key); it != object_sections_.end())
          return fail(line_no, "section [" + sname + "] names the same object as [" + sections_[it->second].name +
                                   "] (line " + std::to_string(sections_[it->second].line) + ")");
        object_sections_[*key] = sections_.size();
      }
      sections_.push_back(Section{sname, line_no, {}});
      current = &sections_.back();
      continue;
    }
    const auto eq = line.find('=');
    if (eq == std::string::npos)
      return fail(line_no, "expected 'key=value', '[section]' or a ';' comment, got " + quote(line));
    const std::string key = trim(std::string_view(line).substr(0, eq));
    if (key.empty()) return fail(line_no, "expected a key before '='");
    if (current == nullptr) return fail(line_no, "expected a [section] before " + quote(key) + "=");
    if (const Key* prev = current->get(key); prev != nullptr) {
      warn(line_no, "duplicate key " + quote(key) + " in [" + current->name + "] ignored: the first, at line " +
                        std::to_string(prev->line) + ", counts");
      continue;
    }
    current->keys.push_back(Key{key, trim(std::string_view(line).substr(eq + 1)), line_no});
  }
  return true;
}

bool Parser::read_value(const Section& s, const Key& k, DataType type, std::optional<Value>& out, bool is_limit) {
  const std::string where = "[" + s.name + "] " + k.name + ": ";
  if (!is_integer(type) && !canopen::is_real(type)) {
    if (is_limit) {
      // CiA 306 gives limits to numbers only; tools write empty ones on strings and domains.
      if (!k.value.empty())
        warn(k.line, where + "a limit on a " + std::string(to_string(type)) + " entry means nothing: ignored");
      out.reset();
      return true;
    }
    out = Value{k.value, false, 0, false};
    return true;
  }
  if (k.value.empty()) {
    out.reset();
    return true;
  }
  if (canopen::is_real(type)) {
    double d = 0;
    if (!parse_real(k.value, d))
      return fail(k.line,
                  where + "expected a real number for " + std::string(to_string(type)) + ", got " + quote(k.value));
    out = Value{k.value, false, 0, false};
    return true;
  }
  Value v;
  if (!parse_value_number(k.value, v))
    return fail(k.line, where + "expected a number (decimal, 0x hex, 0 octal, optionally with $NODEID+), got " +
                            quote(k.value));
  // A signed value written in hexadecimal is the type's two's complement (0x8000 = -32768 for
  // INTEGER16), as EDS tools write limits and defaults.
  const std::size_t width = canopen::fixed_size(type);
  if (canopen::is_signed_integer(type) && width < 8 && upper(v.text).find("0X") != std::string::npos &&
      v.text.find('-') == std::string::npos && v.number < (std::uint64_t{1} << (width * 8)) &&
      (v.number >> (width * 8 - 1)) != 0)
    v.number |= ~std::uint64_t{0} << (width * 8);
  if (!fits(type, v.number))
    return fail(k.line,
                where + "expected a value that fits " + std::string(to_string(type)) + ", got " + quote(k.value));
  out = v;
  return true;
}

bool Parser::read_entry(const Section& s, SubEntry& e, bool var_in_object, bool domain) {
  const std::string where = "[" + s.name + "] ";
  const Key* name = s.get("ParameterName");
  if (name == nullptr || name->value.empty()) return fail(s.line, where + "expected ParameterName=");
  e.name = name->value;
  e.line.number = s.line;
  if (!var_in_object) {
    if (const Key* ot = s.get("ObjectType"); ot != nullptr) {
      std::uint64_t v = 0;
      if (!parse_integer(ot->value, v) || v != 7)
        return fail(ot->line, where + "ObjectType: expected 0x7 (VAR) for a sub-object, got " + quote(ot->value));
    }
  }
  const Key* dt = s.get("DataType");
  std::uint64_t t = static_cast<std::uint64_t>(DataType::Domain);
  if (dt == nullptr && !domain) return fail(s.line, where + "expected DataType=");
  if (dt != nullptr && (!parse_integer(dt->value, t) || !is_known_type(t)))
    return fail(dt->line,
                where + "DataType: expected a CiA 301 data type number such as 0x0007, got " + quote(dt->value));
  e.type = static_cast<DataType>(t);
  const Key* at = s.get("AccessType");
  if (at == nullptr) return fail(s.line, where + "expected AccessType=");
  auto acc = parse_access(at->value);
  if (!acc)
    return fail(at->line, where + "AccessType: expected ro, wo, rw, rwr, rww or const, got " + quote(at->value));
  e.access = *acc;
  if (const Key* pm = s.get("PDOMapping"); pm != nullptr) {
    std::uint64_t v = 0;
    if (!parse_integer(pm->value, v) || v > 1)
      return fail(pm->line, where + "PDOMapping: expected 0 or 1, got " + quote(pm->value));
    e.pdo_mapping = v == 1;
  }
  if (const Key* dv = s.get("DefaultValue"); dv != nullptr && !read_value(s, *dv, e.type, e.default_value, false))
    return false;
  if (const Key* lo = s.get("LowLimit"); lo != nullptr && !read_value(s, *lo, e.type, e.low, true)) return false;
  if (const Key* hi = s.get("HighLimit"); hi != nullptr && !read_value(s, *hi, e.type, e.high, true)) return false;
  if (is_integer(e.type) && e.low && e.high && !e.low->node_relative && !e.high->node_relative) {
    const bool sgn = canopen::is_signed_integer(e.type);
    const bool bad = sgn ? static_cast<std::int64_t>(e.low->number) > static_cast<std::int64_t>(e.high->number)
                         : e.low->number > e.high->number;
    if (bad) return fail(s.get("HighLimit")->line, where + "HighLimit: expected a value not below LowLimit");
  }
  if (is_integer(e.type) && e.default_value && !e.default_value->node_relative) {
    const bool sgn = canopen::is_signed_integer(e.type);
    const std::uint64_t v = e.default_value->number;
    auto below = [&](const Value& l) {
      return sgn ? static_cast<std::int64_t>(v) < static_cast<std::int64_t>(l.number) : v < l.number;
    };
    auto above = [&](const Value& h) {
      return sgn ? static_cast<std::int64_t>(v) > static_cast<std::int64_t>(h.number) : v > h.number;
    };
    if ((e.low && !e.low->node_relative && below(*e.low)) || (e.high && !e.high->node_relative && above(*e.high)))
      warn(s.get("DefaultValue")->line,
           where + "DefaultValue " + quote(e.default_value->text) + " is outside LowLimit..HighLimit: kept as written");
  }
  return true;
}

bool Parser::read_object(File& file, std::uint16_t index, const std::string& list, int list_line) {
  auto it = object_sections_.find(std::uint32_t{index} << 9);
  if (it == object_sections_.end())
    return fail(list_line, "expected a section [" + hex(index, 4) + "] for the object listed in [" + list + "]");
  const Section& s = sections_[it->second];
  const std::string where = "[" + s.name + "] ";
  ObjectEntry o;
  o.index = index;
  o.list = list;
  o.line.number = s.line;
  const Key* name = s.get("ParameterName");
  if (name == nullptr || name->value.empty()) return fail(s.line, where + "expected ParameterName=");
  o.name = name->value;
  std::uint64_t ot = 7;
  if (const Key* k = s.get("ObjectType"); k != nullptr) {
    if (!parse_integer(k->value, ot) || (ot != 2 && ot != 5 && ot != 6 && ot != 7 && ot != 8 && ot != 9))
      return fail(k->line, where +
                               "ObjectType: expected 0x7 (VAR), 0x8 (ARRAY), 0x9 (RECORD), 0x2 (DOMAIN), "
                               "0x5 (DEFTYPE) or 0x6 (DEFSTRUCT), got " +
                               quote(k->value));
  }
  // CiA 306 Table 2: a DOMAIN or a DEFTYPE is held as a VAR, a DEFSTRUCT as a RECORD.
  if (ot == 2 || ot == 5 || ot == 6) o.object_type = static_cast<std::uint8_t>(ot);
  o.code = ot == 8 ? ObjectCode::Array : (ot == 9 || ot == 6) ? ObjectCode::Record : ObjectCode::Var;
  if (const Key* k = s.get("CompactSubObj"); k != nullptr) {
    std::uint64_t v = 0;
    if (!parse_integer(k->value, v) || v > 254)
      return fail(k->line, where + "CompactSubObj: expected the number of sub-objects 0..254, got " + quote(k->value));
    if (v != 0) {
      if (o.code != ObjectCode::Array) {
        warn(k->line, where + "CompactSubObj describes an ARRAY: ObjectType taken as 0x8");
        o.code = ObjectCode::Array;
        o.object_type = 0;
      }
      if (!read_compact(s, o, v)) return false;
      file.objects.emplace(index, std::move(o));
      return true;
    }
  }
  if (o.code == ObjectCode::Var) {
    SubEntry e;
    if (!read_entry(s, e, true, ot == 2)) return false;
    e.sub = 0;
    o.subs.emplace(0, std::move(e));
    file.objects.emplace(index, std::move(o));
    return true;
  }
  const Key* sn = s.get("SubNumber");
  std::uint64_t count = 0;
  if (sn == nullptr) return fail(s.line, where + "expected SubNumber= for an ARRAY/RECORD");
  if (!parse_integer(sn->value, count) || count < 1 || count > 256)
    return fail(sn->line, where + "SubNumber: expected 1..256, got " + quote(sn->value));
  o.sub_number = static_cast<std::uint8_t>(std::min<std::uint64_t>(count, 255));
  const std::uint32_t first = std::uint32_t{index} << 9 | 1;
  const std::uint32_t last = std::uint32_t{index} << 9 | 256;
  for (auto si = object_sections_.lower_bound(first); si != object_sections_.end() && si->first <= last; ++si) {
    SubEntry e;
    e.sub = static_cast<std::uint8_t>((si->first & 0x1FF) - 1);
    if (!read_entry(sections_[si->second], e, false)) return false;
    o.subs.emplace(e.sub, std::move(e));
  }
  if (o.subs.size() != count)
    return fail(sn->line, where + "SubNumber: expected " + std::to_string(count) + " sections [" + hex(index, 4) +
                              "subN], found " + std::to_string(o.subs.size()));
  if (o.subs.find(0) == o.subs.end())
    return fail(s.line, where + "expected a section [" + hex(index, 4) + "sub0] (highest sub-index)");
  file.objects.emplace(index, std::move(o));
  return true;
}

bool Parser::read_compact(const Section& s, ObjectEntry& o, std::uint64_t count) {
  SubEntry proto;
  if (!read_entry(s, proto, true)) return false;
  o.sub_number = static_cast<std::uint8_t>(count + 1);
  SubEntry highest;
  highest.sub = 0;
  highest.name = "Highest sub-index supported";
  highest.type = DataType::Unsigned8;
  highest.access = Access::ReadOnly;
  highest.default_value = Value{std::to_string(count), false, count, true};
  highest.line.number = s.line;
  o.subs.emplace(0, std::move(highest));
  const Section* names = find_section(s.name + "Name");
  const Section* values = find_section(s.name + "Value");
  for (std::uint64_t k = 1; k <= count; ++k) {
    SubEntry e = proto;
    e.sub = static_cast<std::uint8_t>(k);
    e.name = proto.name + std::to_string(k);
    if (names != nullptr)
      if (const Key* n = names->get(std::to_string(k)); n != nullptr && !n->value.empty()) e.name = n->value;
    if (values != nullptr)
      if (const Key* v = values->get(std::to_string(k));
          v != nullptr && !read_value(*values, *v, e.type, e.default_value, false))
        return false;
    o.subs.emplace(e.sub, std::move(e));
  }
  return true;
}

bool Parser::read_lists(File& file) {
  bool any = false;
  for (std::string_view list : kLists) {
    const Section* s = find_section(list);
    if (s == nullptr) continue;
    any = true;
    const std::string where = "[" + s->name + "] ";
    const Key* so = s->get("SupportedObjects");
    if (so == nullptr) return fail(s->line, where + "expected SupportedObjects=");
    std::uint64_t n = 0;
    if (!parse_integer(so->value, n) || n > 0xFFFF)
      return fail(so->line, where + "SupportedObjects: expected a count, got " + quote(so->value));
    for (const Key& k : s->keys) {
      if (&k == so) continue;
      std::uint64_t pos = 0;
      if (!parse_integer(k.name, pos) || pos < 1 || pos > n)
        return fail(k.line, where + "expected entries 1.." + std::to_string(n) + "=<index>, got key " + quote(k.name));
    }
    for (std::uint64_t i = 1; i <= n; ++i) {
      const Key* k = s->get(std::to_string(i));
      if (k == nullptr)
        return fail(so->line, where + "expected an entry " + std::to_string(i) +
                                  "=<index> (SupportedObjects=" + std::to_string(n) + ")");
      std::uint64_t index = 0;
      if (!parse_integer(k->value, index) || index == 0 || index > 0xFFFF)
        return fail(k->line, where + "expected an object index such as 0x1000, got " + quote(k->value));
      if (const ObjectEntry* prev = file.find(static_cast<std::uint16_t>(index)); prev != nullptr)
        return fail(k->line, where + "object " + hex(index, 4) + "h is listed twice (also in [" + prev->list + "])");
      if (!read_object(file, static_cast<std::uint16_t>(index), std::string(list), k->line)) return false;
    }
  }
  if (!any) return fail(last_line_, "expected a [MandatoryObjects] section (the file lists no objects)");
  return true;
}

std::optional<File> Parser::run(std::string_view text) {
  if (!tokenize(text)) return std::nullopt;
  File file;
  file.path = name_;
  if (const Section* di = find_section("DeviceInfo"); di != nullptr)
    for (const Key& k : di->keys) file.device_info[k.name] = k.value;
  if (!read_lists(file)) return std::nullopt;
  file.warnings = std::move(warnings_);
  return file;
}

std::vector<std::uint8_t> value_bytes(const SubEntry& e, canopen::NodeId node) {
  const std::size_t n = canopen::fixed_size(e.type);
  if (!e.default_value) return std::vector<std::uint8_t>(n, 0);
  const Value& v = *e.default_value;
  if (canopen::is_real(e.type)) {
    double d = 0;
    (void)parse_real(v.text, d);
    if (e.type == DataType::Real32) return canopen::encode<float>(static_cast<float>(d));
    return canopen::encode<double>(d);
  }
  if (n == 0) return {v.text.begin(), v.text.end()};
  const std::uint64_t x = v.number + (v.node_relative ? node.value() : 0);
  return canopen::encode_width(x, n);
}

std::optional<canopen::Scalar> limit(const std::optional<Value>& v, DataType t, canopen::NodeId node) {
  if (!v) return std::nullopt;
  if (canopen::is_real(t)) {
    double d = 0;
    if (!parse_real(v->text, d)) return std::nullopt;
    return canopen::Scalar{d};
  }
  if (!v->numeric) return std::nullopt;
  const std::uint64_t x = v->number + (v->node_relative ? node.value() : 0);
  if (canopen::is_signed_integer(t)) return canopen::Scalar{static_cast<std::int64_t>(x)};
  return canopen::Scalar{x};
}

canopen::SubObject make_sub(const SubEntry& e, canopen::NodeId node) {
  canopen::SubObject s;
  s.sub_index = e.sub;
  s.name = e.name;
  s.type = e.type;
  s.access = e.access;
  s.pdo_mappable = e.pdo_mapping;
  s.default_value = value_bytes(e, node);
  s.value = s.default_value;
  s.low = limit(e.low, e.type, node);
  s.high = limit(e.high, e.type, node);
  if (canopen::fixed_size(e.type) == 0) s.max_size = std::max<std::size_t>(256, s.default_value.size());
  return s;
}

void write_entry(std::ostringstream& os, const SubEntry& e, bool sub_section) {
  os << "ParameterName=" << e.name << "\n";
  if (sub_section) os << "ObjectType=0x7\n";
  os << "DataType=0x" << hex(static_cast<std::uint16_t>(e.type), 4) << "\n";
  os << "AccessType=" << canopen::to_string(e.access) << "\n";
  if (e.default_value) os << "DefaultValue=" << e.default_value->text << "\n";
  if (e.low) os << "LowLimit=" << e.low->text << "\n";
  if (e.high) os << "HighLimit=" << e.high->text << "\n";
  os << "PDOMapping=" << (e.pdo_mapping ? 1 : 0) << "\n";
}

}  // namespace

std::optional<std::uint32_t> File::device_number(std::string_view key) const {
  for (const auto& [k, v] : device_info) {
    if (!iequals(k, key)) continue;
    std::uint64_t n = 0;
    if (!parse_integer(v, n) || n > 0xFFFFFFFFu) return std::nullopt;
    return static_cast<std::uint32_t>(n);
  }
  return std::nullopt;
}

std::optional<std::uint64_t> File::default_number(std::uint16_t index, std::uint8_t sub, canopen::NodeId node) const {
  const SubEntry* e = find(index, sub);
  if (e == nullptr || !e->default_value || !e->default_value->numeric) return std::nullopt;
  return e->default_value->number + (e->default_value->node_relative ? node.value() : 0);
}

std::optional<File> parse(std::string_view text, std::string_view name, std::string& error) {
  Parser p(name, error);
  return p.run(text);
}

std::optional<File> load(const std::filesystem::path& path, std::string& error) {
  const auto file = read_text_file(path.string(), kMaxFileBytes);
  if (!file.text) {
    error = path.string() + ": " + file.error + " (an EDS file)";
    return std::nullopt;
  }
  return parse(*file.text, path.string(), error);
}

std::string write(const File& file) {
  std::ostringstream os;
  os << "; written by oegw (CiA 306 EDS)\n";
  if (!file.device_info.empty()) {
    os << "[DeviceInfo]\n";
    for (const auto& [k, v] : file.device_info) os << k << "=" << v << "\n";
    os << "\n";
  }
  for (std::string_view list : kLists) {
    std::vector<std::uint16_t> members;
    for (const auto& [idx, o] : file.objects)
      if (o.list == list || (o.list.empty() && list == "OptionalObjects")) members.push_back(idx);
    if (members.empty()) continue;
    os << "[" << list << "]\nSupportedObjects=" << members.size() << "\n";
    for (std::size_t i = 0; i < members.size(); ++i) os << i + 1 << "=0x" << hex(members[i], 4) << "\n";
    os << "\n";
  }
  for (const auto& [idx, o] : file.objects) {
    os << "[" << hex(idx, 4) << "]\n";
    if (o.code == ObjectCode::Var) {
      os << "ObjectType=0x" << (o.object_type != 0 ? static_cast<int>(o.object_type) : 7) << "\n";
      if (const SubEntry* e = o.find(0); e != nullptr) write_entry(os, *e, false);
      os << "\n";
      continue;
    }
    os << "ParameterName=" << o.name << "\n";
    os << "ObjectType=0x" << (o.object_type != 0 ? static_cast<int>(o.object_type) : static_cast<int>(o.code)) << "\n";
    os << "SubNumber=" << o.subs.size() << "\n\n";
    for (const auto& [si, e] : o.subs) {
      os << "[" << hex(idx, 4) << "sub" << hex(si, 1) << "]\n";
      write_entry(os, e, true);
      os << "\n";
    }
  }
  return os.str();
}

std::unique_ptr<canopen::ObjectDictionary> build_dictionary(const File& file, canopen::NodeId node) {
  auto od = std::make_unique<canopen::ObjectDictionary>();
  for (const auto& [idx, o] : file.objects) {
    if (o.code == ObjectCode::Var) {
      const SubEntry* e = o.find(0);
      if (e == nullptr) continue;
      od->add_var(idx, o.name, e->type, e->access, {}, e->pdo_mapping);
      od->find(idx)->add_sub(make_sub(*e, node));
      continue;
    }
    canopen::Object* obj = nullptr;
    if (o.code == ObjectCode::Array) {
      const SubEntry* first = o.find(1);
      obj = &od->add_array(idx, o.name, first != nullptr ? first->type : DataType::Unsigned8, Access::ReadOnly, 0, {});
    } else {
      obj = &od->add_record(idx, o.name);
    }
    for (const auto& [si, e] : o.subs) obj->add_sub(make_sub(e, node));
  }
  return od;
}

std::optional<canopen::PdoParameters> pdo_defaults(const File& file, bool transmit, std::uint16_t n,
                                                   canopen::NodeId node) {
  if (n < 1 || n > 512) return std::nullopt;
  const auto ci = static_cast<std::uint16_t>((transmit ? 0x1800 : 0x1400) + n - 1);
  const auto mi = static_cast<std::uint16_t>((transmit ? 0x1A00 : 0x1600) + n - 1);
  const ObjectEntry* comm = file.find(ci);
  const ObjectEntry* map = file.find(mi);
  if (comm == nullptr || map == nullptr) return std::nullopt;
  canopen::PdoParameters p;
  p.cob_id = static_cast<std::uint32_t>(file.default_number(ci, 1, node).value_or(canopen::CobId::kInvalidBit));
  p.transmission_type = static_cast<std::uint8_t>(file.default_number(ci, 2, node).value_or(0xFF));
  p.inhibit_time = static_cast<std::uint16_t>(file.default_number(ci, 3, node).value_or(0));
  p.event_timer = static_cast<std::uint16_t>(file.default_number(ci, 5, node).value_or(0));
  p.sync_start = static_cast<std::uint8_t>(file.default_number(ci, 6, node).value_or(0));
  const auto count = std::min<std::uint64_t>(file.default_number(mi, 0, node).value_or(0), 64);
  for (std::uint64_t i = 1; i <= count; ++i)
    p.mapping.push_back(
        static_cast<std::uint32_t>(file.default_number(mi, static_cast<std::uint8_t>(i), node).value_or(0)));
  std::uint8_t highest = 0;
  for (const auto& [si, e] : map->subs) highest = std::max(highest, si);
  p.mapping_capacity = static_cast<std::uint8_t>(std::clamp<std::size_t>(std::max<std::size_t>(highest, count), 1, 64));
  return p;
}

}  // namespace oegw::canopen::eds
