#include "canopen/301/object_dictionary.hpp"

#include <algorithm>
#include <cstdio>

#include "canopen/state.hpp"

namespace oegw::canopen {

std::size_t fixed_size(DataType t) {
  switch (t) {
    case DataType::Boolean:
    case DataType::Integer8:
    case DataType::Unsigned8: return 1;
    case DataType::Integer16:
    case DataType::Unsigned16: return 2;
    case DataType::Integer24:
    case DataType::Unsigned24: return 3;
    case DataType::Integer32:
    case DataType::Unsigned32:
    case DataType::Real32: return 4;
    case DataType::Integer40:
    case DataType::Unsigned40: return 5;
    case DataType::Integer48:
    case DataType::Unsigned48:
    case DataType::TimeOfDay:
    case DataType::TimeDifference: return 6;
    case DataType::Integer56:
    case DataType::Unsigned56: return 7;
    case DataType::Integer64:
    case DataType::Unsigned64:
    case DataType::Real64: return 8;
    case DataType::VisibleString:
    case DataType::OctetString:
    case DataType::UnicodeString:
    case DataType::Domain: return 0;
  }
  return 0;
}

bool is_signed_integer(DataType t) {
  switch (t) {
    case DataType::Integer8:
    case DataType::Integer16:
    case DataType::Integer24:
    case DataType::Integer32:
    case DataType::Integer40:
    case DataType::Integer48:
    case DataType::Integer56:
    case DataType::Integer64: return true;
    default: return false;
  }
}

bool is_unsigned_integer(DataType t) {
  switch (t) {
    case DataType::Boolean:
    case DataType::Unsigned8:
    case DataType::Unsigned16:
    case DataType::Unsigned24:
    case DataType::Unsigned32:
    case DataType::Unsigned40:
    case DataType::Unsigned48:
    case DataType::Unsigned56:
    case DataType::Unsigned64: return true;
    default: return false;
  }
}

bool is_real(DataType t) { return t == DataType::Real32 || t == DataType::Real64; }

std::string_view to_string(DataType t) {
  switch (t) {
    case DataType::Boolean: return "BOOLEAN";
    case DataType::Integer8: return "INTEGER8";
    case DataType::Integer16: return "INTEGER16";
    case DataType::Integer32: return "INTEGER32";
    case DataType::Unsigned8: return "UNSIGNED8";
    case DataType::Unsigned16: return "UNSIGNED16";
    case DataType::Unsigned32: return "UNSIGNED32";
    case DataType::Real32: return "REAL32";
    case DataType::VisibleString: return "VISIBLE_STRING";
    case DataType::OctetString: return "OCTET_STRING";
    case DataType::UnicodeString: return "UNICODE_STRING";
    case DataType::TimeOfDay: return "TIME_OF_DAY";
    case DataType::TimeDifference: return "TIME_DIFFERENCE";
    case DataType::Domain: return "DOMAIN";
    case DataType::Integer24: return "INTEGER24";
    case DataType::Real64: return "REAL64";
    case DataType::Integer40: return "INTEGER40";
    case DataType::Integer48: return "INTEGER48";
    case DataType::Integer56: return "INTEGER56";
    case DataType::Integer64: return "INTEGER64";
    case DataType::Unsigned24: return "UNSIGNED24";
    case DataType::Unsigned40: return "UNSIGNED40";
    case DataType::Unsigned48: return "UNSIGNED48";
    case DataType::Unsigned56: return "UNSIGNED56";
    case DataType::Unsigned64: return "UNSIGNED64";
  }
  return "UNKNOWN";
}

std::string_view to_string(Access a) {
  switch (a) {
    case Access::ReadOnly: return "ro";
    case Access::WriteOnly: return "wo";
    case Access::ReadWrite: return "rw";
    case Access::ReadWriteRead: return "rwr";
    case Access::ReadWriteWrite: return "rww";
    case Access::Const: return "const";
  }
  return "ro";
}

bool readable(Access a) { return a != Access::WriteOnly; }
bool writable(Access a) {
  return a == Access::WriteOnly || a == Access::ReadWrite || a == Access::ReadWriteRead || a == Access::ReadWriteWrite;
}

std::vector<std::uint8_t> encode_width(std::uint64_t v, std::size_t width) {
  std::vector<std::uint8_t> out(width);
  put_little_endian(v, out);
  return out;
}

std::uint64_t decode_unsigned(std::span<const std::uint8_t> bytes) {
  std::uint64_t v = 0;
  const std::size_t n = std::min<std::size_t>(bytes.size(), 8);
  for (std::size_t i = 0; i < n; ++i) v |= static_cast<std::uint64_t>(bytes[i]) << (8 * i);
  return v;
}

std::int64_t decode_signed(std::span<const std::uint8_t> bytes) {
  const std::size_t n = std::min<std::size_t>(bytes.size(), 8);
  std::uint64_t v = decode_unsigned(bytes);
  if (n > 0 && n < 8 && (bytes[n - 1] & 0x80) != 0) v |= ~std::uint64_t{0} << (8 * n);
  return static_cast<std::int64_t>(v);
}

SubObject& Object::add_sub(SubObject sub) {
  if (sub.value.empty() && !sub.default_value.empty()) sub.value = sub.default_value;
  if (sub.default_value.empty() && !sub.value.empty()) sub.default_value = sub.value;
  const std::uint8_t si = sub.sub_index;
  auto [it, inserted] = subs_.insert_or_assign(si, std::move(sub));
  (void)inserted;
  return it->second;
}

SubObject* Object::find(std::uint8_t sub) {
  auto it = subs_.find(sub);
  return it == subs_.end() ? nullptr : &it->second;
}

const SubObject* Object::find(std::uint8_t sub) const {
  auto it = subs_.find(sub);
  return it == subs_.end() ? nullptr : &it->second;
}

Subscription Object::add_write_hook(WriteHook hook) {
  if (!hooks_) hooks_ = std::make_shared<detail::CallbackList<WriteHook>>();
  const std::uint64_t id = hooks_->add(std::move(hook));
  return Subscription(hooks_, id);
}

SdoAbortCode Object::run_hooks(std::uint8_t sub, std::span<const std::uint8_t> bytes, Origin origin) {
  if (!hooks_) return SdoAbortCode::None;
  const auto keep = hooks_;  // a hook may replace this Object; its list stays alive until we return
  SdoAbortCode c = SdoAbortCode::None;
  keep->for_each_until([&](WriteHook& h) {
    c = h(*this, sub, bytes, origin);
    return c != SdoAbortCode::None;
  });
  return c;
}

namespace {

std::vector<std::uint8_t> sized_default(DataType type, std::vector<std::uint8_t> v) {
  const std::size_t n = fixed_size(type);
  if (n != 0) v.resize(n, 0);
  return v;
}

// CiA 301 §7.2.4.3.17: a value outside the object's limits is refused with 0609 0031h/0032h.
SdoAbortCode check_limits(const SubObject& s, std::span<const std::uint8_t> bytes) {
  if (s.type == DataType::Boolean && !bytes.empty() && bytes[0] > 1) return SdoAbortCode::ValueTooHigh;
  if (!s.low && !s.high) return SdoAbortCode::None;
  if (is_signed_integer(s.type)) {
    const std::int64_t v = decode_signed(bytes);
    if (s.low && std::holds_alternative<std::int64_t>(*s.low) && v < std::get<std::int64_t>(*s.low))
      return SdoAbortCode::ValueTooLow;
    if (s.high && std::holds_alternative<std::int64_t>(*s.high) && v > std::get<std::int64_t>(*s.high))
      return SdoAbortCode::ValueTooHigh;
  } else if (is_unsigned_integer(s.type)) {
    const std::uint64_t v = decode_unsigned(bytes);
    if (s.low && std::holds_alternative<std::uint64_t>(*s.low) && v < std::get<std::uint64_t>(*s.low))
      return SdoAbortCode::ValueTooLow;
    if (s.high && std::holds_alternative<std::uint64_t>(*s.high) && v > std::get<std::uint64_t>(*s.high))
      return SdoAbortCode::ValueTooHigh;
  } else if (is_real(s.type)) {
    double v = 0;
    if (s.type == DataType::Real32) {
      float f = 0;
      std::memcpy(&f, bytes.data(), sizeof f);
      v = f;
    } else {
      std::memcpy(&v, bytes.data(), sizeof v);
    }
    if (s.low && std::holds_alternative<double>(*s.low) && v < std::get<double>(*s.low))
      return SdoAbortCode::ValueTooLow;
    if (s.high && std::holds_alternative<double>(*s.high) && v > std::get<double>(*s.high))
      return SdoAbortCode::ValueTooHigh;
  }
  return SdoAbortCode::None;
}

}  // namespace

Object& ObjectDictionary::add_var(std::uint16_t index, std::string name, DataType type, Access access,
                                  std::vector<std::uint8_t> default_value, bool pdo_mappable) {
  ++layout_;
  auto [it, inserted] = objects_.insert_or_assign(index, Object(index, name, ObjectCode::Var));
  (void)inserted;
  index_[index] = &it->second;
  SubObject s;
  s.sub_index = 0;
  s.name = std::move(name);
  s.type = type;
  s.access = access;
  s.pdo_mappable = pdo_mappable;
  s.default_value = sized_default(type, std::move(default_value));
  it->second.add_sub(std::move(s));
  return it->second;
}

Object& ObjectDictionary::add_array(std::uint16_t index, std::string name, DataType type, Access access,
                                    std::uint8_t count, std::vector<std::uint8_t> default_value, bool pdo_mappable) {
  ++layout_;
  auto [it, inserted] = objects_.insert_or_assign(index, Object(index, name, ObjectCode::Array));
  (void)inserted;
  index_[index] = &it->second;
  SubObject s0;
  s0.sub_index = 0;
  s0.name = "Highest sub-index supported";
  s0.type = DataType::Unsigned8;
  s0.access = Access::ReadOnly;
  s0.default_value = {count};
  it->second.add_sub(std::move(s0));
  const auto dv = sized_default(type, std::move(default_value));
  for (unsigned i = 1; i <= count; ++i) {
    SubObject s;
    s.sub_index = static_cast<std::uint8_t>(i);
    s.name = name + " " + std::to_string(i);
    s.type = type;
    s.access = access;
    s.pdo_mappable = pdo_mappable;
    s.default_value = dv;
    it->second.add_sub(std::move(s));
  }
  return it->second;
}

Object& ObjectDictionary::add_record(std::uint16_t index, std::string name) {
  ++layout_;
  auto [it, inserted] = objects_.insert_or_assign(index, Object(index, std::move(name), ObjectCode::Record));
  (void)inserted;
  index_[index] = &it->second;
  SubObject s0;
  s0.sub_index = 0;
  s0.name = "Highest sub-index supported";
  s0.type = DataType::Unsigned8;
  s0.access = Access::ReadOnly;
  s0.default_value = {0};
  it->second.add_sub(std::move(s0));
  return it->second;
}

SubObject& ObjectDictionary::add_record_member(std::uint16_t index, std::uint8_t sub, std::string name, DataType type,
                                               Access access, std::vector<std::uint8_t> default_value,
                                               bool pdo_mappable) {
  Object* obj = find(index);
  if (obj == nullptr) obj = &add_record(index, "Record " + std::to_string(index));
  SubObject s;
  s.sub_index = sub;
  s.name = std::move(name);
  s.type = type;
  s.access = access;
  s.pdo_mappable = pdo_mappable;
  s.default_value = sized_default(type, std::move(default_value));
  SubObject& added = obj->add_sub(std::move(s));
  SubObject* s0 = obj->find(0);
  if (s0 != nullptr && sub != 0 && s0->value.size() == 1 && s0->value[0] < sub) {
    s0->value[0] = sub;
    s0->default_value[0] = sub;
  }
  return added;
}

Subscription ObjectDictionary::add_observer(ChangeObserver obs) {
  const std::uint64_t id = observers_->add(std::move(obs));
  return Subscription(observers_, id);
}

bool ObjectDictionary::remove(std::uint16_t index) {
  ++layout_;
  index_.erase(index);
  return objects_.erase(index) != 0;
}

Object* ObjectDictionary::find(std::uint16_t index) {
  const auto it = index_.find(index);
  return it == index_.end() ? nullptr : it->second;
}
const Object* ObjectDictionary::find(std::uint16_t index) const {
  const auto it = index_.find(index);
  return it == index_.end() ? nullptr : it->second;
}
SubObject* ObjectDictionary::find(std::uint16_t index, std::uint8_t sub) {
  Object* o = find(index);
  return o == nullptr ? nullptr : o->find(sub);
}
const SubObject* ObjectDictionary::find(std::uint16_t index, std::uint8_t sub) const {
  const Object* o = find(index);
  return o == nullptr ? nullptr : o->find(sub);
}

SdoAbortCode ObjectDictionary::check_read(std::uint16_t index, std::uint8_t sub, Origin origin) const {
  const Object* o = find(index);
  if (o == nullptr) return SdoAbortCode::ObjectDoesNotExist;
  const SubObject* s = o->find(sub);
  if (s == nullptr) return SdoAbortCode::SubIndexDoesNotExist;
  if (origin == Origin::Local) return SdoAbortCode::None;
  if (!readable(s->access)) return SdoAbortCode::ReadOfWriteOnly;
  if (origin == Origin::Pdo && (!s->pdo_mappable || s->access == Access::ReadWriteWrite))
    return SdoAbortCode::CannotBeMapped;
  return SdoAbortCode::None;
}

SdoAbortCode ObjectDictionary::check_write(std::uint16_t index, std::uint8_t sub, Origin origin) const {
  const Object* o = find(index);
  if (o == nullptr) return SdoAbortCode::ObjectDoesNotExist;
  const SubObject* s = o->find(sub);
  if (s == nullptr) return SdoAbortCode::SubIndexDoesNotExist;
  if (origin == Origin::Local) return SdoAbortCode::None;
  if (!writable(s->access)) return SdoAbortCode::WriteOfReadOnly;
  if (origin == Origin::Pdo && (!s->pdo_mappable || s->access == Access::ReadWriteRead))
    return SdoAbortCode::CannotBeMapped;
  return SdoAbortCode::None;
}

SdoAbortCode ObjectDictionary::read(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t>& out,
                                    Origin origin) const {
  const SdoAbortCode c = check_read(index, sub, origin);
  if (c != SdoAbortCode::None) return c;
  out = find(index, sub)->value;
  return SdoAbortCode::None;
}

SdoAbortCode ObjectDictionary::write(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> bytes,
                                     Origin origin) {
  const SdoAbortCode c = check_write(index, sub, origin);
  if (c != SdoAbortCode::None) return c;
  Object& obj = *find(index);
  return write_resolved(obj, *obj.find(sub), bytes, origin);
}

SubObject* ObjectDictionary::resolve(Slot& slot) {
  if (slot.layout != layout_) {
    slot.object = find(slot.index);
    slot.entry = slot.object != nullptr ? slot.object->find(slot.sub) : nullptr;
    slot.layout = layout_;
  }
  return slot.entry;
}

SdoAbortCode ObjectDictionary::set_local(Slot& slot, std::int64_t v) {
  SubObject* s = resolve(slot);
  const std::size_t width = s != nullptr ? s->value.size() : 0;
  if (s == nullptr || width > 8) return set<std::int64_t>(slot.index, slot.sub, v, Origin::Local);
  std::array<std::uint8_t, 8> buf{};
  put_little_endian(static_cast<std::uint64_t>(v), std::span<std::uint8_t>(buf.data(), width));
  return write_resolved(*slot.object, *s, std::span<const std::uint8_t>(buf.data(), width), Origin::Local);
}

SdoAbortCode ObjectDictionary::write_resolved(Object& obj, SubObject& s, std::span<const std::uint8_t> bytes,
                                              Origin origin) {
  const std::size_t n = fixed_size(s.type);
  if (n != 0) {
    if (bytes.size() > n) return SdoAbortCode::LengthTooHigh;
    if (bytes.size() < n) return SdoAbortCode::LengthTooLow;
  } else if (bytes.size() > s.max_size) {
    return SdoAbortCode::LengthTooHigh;
  }
  if (const SdoAbortCode lc = check_limits(s, bytes); lc != SdoAbortCode::None) return lc;
  if (const SdoAbortCode hc = obj.run_hooks(s.sub_index, bytes, origin); hc != SdoAbortCode::None) return hc;
  s.value.assign(bytes.begin(), bytes.end());
  const std::uint16_t index = obj.index();  // an observer may replace the Object
  const std::uint8_t si = s.sub_index;
  const auto keep = observers_;
  keep->for_each_until([&](ChangeObserver& o) {
    o(index, si, origin);
    return false;
  });
  return SdoAbortCode::None;
}

void ObjectDictionary::reset_to_defaults(std::uint16_t first, std::uint16_t last) {
  for (auto it = objects_.lower_bound(first); it != objects_.end() && it->first <= last; ++it) {
    for (auto& [si, s] : it->second.subs()) s.value = s.default_value;
  }
}

namespace {

// "1017.00": the key of an entry's value.
std::string value_key(std::uint16_t index, std::uint8_t sub) {
  char key[8];
  std::snprintf(key, sizeof key, "%04x.%02x", index, sub);
  return key;
}

}  // namespace

std::uint64_t ObjectDictionary::layout_fingerprint() const {
  // FNV-1a over every entry's index, sub-index, type, default and size limit, in order: values
  // equal to their default are not exported, so two dictionaries whose defaults differ (another
  // node-ID: 1014h, the PDO COB-IDs) are other configurations.
  std::uint64_t h = 0xcbf29ce484222325u;
  const auto mix = [&h](std::uint64_t v, int bytes) {
    for (int i = 0; i < bytes; ++i) {
      h ^= (v >> (8 * i)) & 0xFF;
      h *= 0x100000001b3u;
    }
  };
  for (const auto& [index, obj] : objects_) {
    for (const auto& [si, s] : obj.subs()) {
      mix(index, 2);
      mix(si, 1);
      mix(static_cast<std::uint64_t>(s.type), 2);
      mix(s.max_size, 4);
      mix(s.default_value.size(), 2);
      for (const std::uint8_t b : s.default_value) mix(b, 1);
    }
  }
  return h;
}

void ObjectDictionary::export_values(StateWriter& w) const {
  w.put("layout", layout_fingerprint());
  for (const auto& [index, obj] : objects_) {
    for (const auto& [si, s] : obj.subs()) {
      if (s.value != s.default_value) w.put_bytes(value_key(index, si), s.value);
    }
  }
}

void ObjectDictionary::import_values(const StateReader& r) {
  if (r.get<std::uint64_t>("layout") != layout_fingerprint()) {
    r.fail("layout", "differs from this dictionary's (another configuration or version)");
  }
  // Every value checked before any is set: a refused state changes nothing.
  std::vector<std::pair<SubObject*, std::vector<std::uint8_t>>> values;
  for (auto& [index, obj] : objects_) {
    for (auto& [si, s] : obj.subs()) {
      const std::string key = value_key(index, si);
      if (!r.has(key)) {
        values.emplace_back(&s, s.default_value);
        continue;
      }
      std::vector<std::uint8_t> v = r.bytes(key);
      const std::size_t fixed = fixed_size(s.type);
      if (fixed != 0 && v.size() != fixed) {
        r.fail(key, "is " + std::to_string(v.size()) + " bytes, " + std::string(to_string(s.type)) + " takes " +
                        std::to_string(fixed));
      }
      if (fixed == 0 && v.size() > s.max_size) {
        r.fail(key, "is longer than its entry's " + std::to_string(s.max_size) + " bytes");
      }
      values.emplace_back(&s, std::move(v));
    }
  }
  for (auto& [s, v] : values) s->value = std::move(v);
}

}  // namespace oegw::canopen
