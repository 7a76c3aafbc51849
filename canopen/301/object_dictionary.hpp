// The object dictionary (CiA 301 §7.4): every object a node exposes, with its data type,
// access, PDO-mappability, limits, default and current value.
//
// Values are kept as their little-endian wire bytes (CiA 301 §7.1), so SDO and PDO copy them
// without conversion. Objects and sub-objects live in std::map nodes: their addresses are stable,
// so a PDO may keep a pointer to the bytes it maps.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <functional>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <type_traits>
#include <unordered_map>
#include <variant>
#include <vector>

#include "canopen/301/subscription.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen {

class StateWriter;  // canopen/state.hpp
class StateReader;

// CiA 301 §7.4.7.1, Table 44: static data types (the index of their DEFTYPE entry).
enum class DataType : std::uint16_t {
  Boolean = 0x0001,
  Integer8 = 0x0002,
  Integer16 = 0x0003,
  Integer32 = 0x0004,
  Unsigned8 = 0x0005,
  Unsigned16 = 0x0006,
  Unsigned32 = 0x0007,
  Real32 = 0x0008,
  VisibleString = 0x0009,
  OctetString = 0x000A,
  UnicodeString = 0x000B,
  TimeOfDay = 0x000C,
  TimeDifference = 0x000D,
  Domain = 0x000F,
  Integer24 = 0x0010,
  Real64 = 0x0011,
  Integer40 = 0x0012,
  Integer48 = 0x0013,
  Integer56 = 0x0014,
  Integer64 = 0x0015,
  Unsigned24 = 0x0016,
  Unsigned40 = 0x0018,
  Unsigned48 = 0x0019,
  Unsigned56 = 0x001A,
  Unsigned64 = 0x001B,
};

// Size in bytes of a fixed-size type; 0 for the variable-size ones (strings, DOMAIN).
[[nodiscard]] std::size_t fixed_size(DataType t);
[[nodiscard]] bool is_signed_integer(DataType t);
[[nodiscard]] bool is_unsigned_integer(DataType t);  // includes BOOLEAN
[[nodiscard]] bool is_real(DataType t);
[[nodiscard]] std::string_view to_string(DataType t);  // "UNSIGNED32", as in EDS files (CiA 306)

// CiA 301 §7.4.3 / CiA 306 AccessType. rwr/rww say in which PDO direction an rw object maps.
enum class Access : std::uint8_t { ReadOnly, WriteOnly, ReadWrite, ReadWriteRead, ReadWriteWrite, Const };
[[nodiscard]] std::string_view to_string(Access a);  // "ro", "wo", "rw", "rwr", "rww", "const"
[[nodiscard]] bool readable(Access a);
[[nodiscard]] bool writable(Access a);

// CiA 301 §7.4.3, Table 42: object codes.
enum class ObjectCode : std::uint8_t { Var = 7, Array = 8, Record = 9 };

// Who is writing: an SDO client honours the access type; an RPDO needs a mappable, writable
// entry; the application itself (Local) may update read-only objects such as its inputs.
enum class Origin : std::uint8_t { Sdo, Pdo, Local };

// A numeric limit, in the signedness of the object's type.
using Scalar = std::variant<std::int64_t, std::uint64_t, double>;

struct SubObject {
  std::uint8_t sub_index = 0;
  std::string name;
  DataType type = DataType::Unsigned8;
  Access access = Access::ReadOnly;
  bool pdo_mappable = false;
  std::vector<std::uint8_t> value;
  std::vector<std::uint8_t> default_value;
  std::optional<Scalar> low;   // inclusive
  std::optional<Scalar> high;  // inclusive
  std::size_t max_size = 256;  // accepted length of VISIBLE_STRING/OCTET_STRING/DOMAIN values

  [[nodiscard]] std::size_t bit_length() const { return value.size() * 8; }
};

class Object;

// Called before a write (from SDO, PDO or Local) commits. Return SdoAbortCode::None to accept,
// or the abort code that refuses it; a refused write changes nothing.
using WriteHook =
    std::function<SdoAbortCode(Object& obj, std::uint8_t sub, std::span<const std::uint8_t> bytes, Origin origin)>;
// Called after a write has committed.
using ChangeObserver = std::function<void(std::uint16_t index, std::uint8_t sub, Origin origin)>;

class Object {
 public:
  Object(std::uint16_t index, std::string name, ObjectCode code) : index_(index), name_(std::move(name)), code_(code) {}
  // Move-only: the write hooks capture their services and belong to exactly one Object.
  Object(const Object&) = delete;
  Object& operator=(const Object&) = delete;
  Object(Object&&) noexcept = default;
  Object& operator=(Object&&) noexcept = default;

  [[nodiscard]] std::uint16_t index() const { return index_; }
  [[nodiscard]] const std::string& name() const { return name_; }
  [[nodiscard]] ObjectCode code() const { return code_; }

  SubObject& add_sub(SubObject sub);
  [[nodiscard]] SubObject* find(std::uint8_t sub);
  [[nodiscard]] const SubObject* find(std::uint8_t sub) const;
  [[nodiscard]] const std::map<std::uint8_t, SubObject>& subs() const { return subs_; }
  [[nodiscard]] std::map<std::uint8_t, SubObject>& subs() { return subs_; }

  // Several hooks may be installed; the first that refuses wins. The hook stays installed as
  // long as the returned Subscription lives (and the Object exists: removing or replacing the
  // Object drops its hooks, and the Subscription then releases nothing).
  Subscription add_write_hook(WriteHook hook);
  [[nodiscard]] std::size_t write_hook_count() const { return hooks_ ? hooks_->size() : 0; }
  [[nodiscard]] SdoAbortCode run_hooks(std::uint8_t sub, std::span<const std::uint8_t> bytes, Origin origin);

 private:
  std::uint16_t index_;
  std::string name_;
  ObjectCode code_;
  std::map<std::uint8_t, SubObject> subs_;
  std::shared_ptr<detail::CallbackList<WriteHook>> hooks_;  // created by the first add_write_hook
};

// Encode/decode a C++ value to/from its CANopen little-endian bytes.
template <class T>
std::vector<std::uint8_t> encode(T v) {
  static_assert(std::is_arithmetic_v<T>);
  std::vector<std::uint8_t> out(sizeof(T));
  std::memcpy(out.data(), &v, sizeof(T));  // x86/ARM Linux targets are little endian
  return out;
}
// Bytes of `width` (1..8) taken from a value, e.g. an INTEGER24 from an int32.
std::vector<std::uint8_t> encode_width(std::uint64_t v, std::size_t width);
// The same into `out` in place (no allocation): its bytes least significant first (CiA 301
// §7.1.2, numbers are transferred little endian), those past the eighth 0.
inline void put_little_endian(std::uint64_t v, std::span<std::uint8_t> out) {
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = static_cast<std::uint8_t>(i < 8 ? v >> (8 * i) : 0);
}

[[nodiscard]] std::uint64_t decode_unsigned(std::span<const std::uint8_t> bytes);
[[nodiscard]] std::int64_t decode_signed(std::span<const std::uint8_t> bytes);  // sign-extends

class ObjectDictionary {
 public:
  ObjectDictionary() : observers_(std::make_shared<detail::CallbackList<ChangeObserver>>()) {}
  ObjectDictionary(const ObjectDictionary&) = delete;
  ObjectDictionary& operator=(const ObjectDictionary&) = delete;

  // Builders. A VAR gets one sub-object (sub-index 0). An ARRAY gets sub-index 0 ("highest
  // sub-index supported", UNSIGNED8, ro by default) and `count` elements 1..count.
  Object& add_var(std::uint16_t index, std::string name, DataType type, Access access,
                  std::vector<std::uint8_t> default_value, bool pdo_mappable = false);
  Object& add_array(std::uint16_t index, std::string name, DataType type, Access access, std::uint8_t count,
                    std::vector<std::uint8_t> default_value, bool pdo_mappable = false);
  // A RECORD with only sub-index 0; add the members with Object::add_sub (sub-index 0 is kept
  // equal to the highest sub-index by add_record_member).
  Object& add_record(std::uint16_t index, std::string name);
  SubObject& add_record_member(std::uint16_t index, std::uint8_t sub, std::string name, DataType type, Access access,
                               std::vector<std::uint8_t> default_value, bool pdo_mappable = false);
  // Removes an object (used when a profile object is conditional). Returns false if absent.
  bool remove(std::uint16_t index);

  [[nodiscard]] Object* find(std::uint16_t index);
  [[nodiscard]] const Object* find(std::uint16_t index) const;
  [[nodiscard]] SubObject* find(std::uint16_t index, std::uint8_t sub);
  [[nodiscard]] const SubObject* find(std::uint16_t index, std::uint8_t sub) const;
  [[nodiscard]] const std::map<std::uint16_t, Object>& objects() const { return objects_; }

  // Counted up whenever an object is added, replaced or removed (the builders, remove()): a
  // SubObject's address holds while it is unchanged. Object::add_sub() keeps the addresses of
  // the other sub-objects (map nodes); a sub-object erased through Object::subs() is not counted
  // (done only while a dictionary is built, before anyone keeps an address).
  [[nodiscard]] std::uint64_t layout() const { return layout_; }
  // A sub-object looked up once for a writer that writes it with every frame (the gateway's
  // inputs): resolve() gives its address without a look-up while layout() is unchanged since,
  // and looks it up again when it has changed. nullptr: no such sub-object.
  struct Slot {
    std::uint16_t index = 0;
    std::uint8_t sub = 0;
    Object* object = nullptr;
    SubObject* entry = nullptr;
    std::uint64_t layout = ~std::uint64_t{0};
  };
  [[nodiscard]] SubObject* resolve(Slot& slot);
  // get() through a slot: 0 for a missing entry, as get() by index.
  template <class T>
  [[nodiscard]] T get(Slot& slot) {
    return value_as<T>(resolve(slot));
  }
  // set<std::int64_t>(slot.index, slot.sub, v, Origin::Local) through the slot: the same checks
  // (length, limits, hooks), observers and result, without the three look-ups.
  SdoAbortCode set_local(Slot& slot, std::int64_t v);

  // What an SDO upload/download, an RPDO or the application does. Checks existence, access for
  // the origin, length for fixed-size types, limits, then the object's hooks; commits only when
  // all accept, then notifies observers.
  [[nodiscard]] SdoAbortCode read(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t>& out,
                                  Origin origin = Origin::Sdo) const;
  [[nodiscard]] SdoAbortCode write(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> bytes,
                                   Origin origin = Origin::Sdo);
  // The commit half of write() for a caller that has already resolved the entry and checked
  // its access with check_write() (an RPDO resolves its mapping once, when the mapping becomes
  // valid, so the per-frame path does no map look-ups). Checks length, limits and hooks,
  // commits, then notifies observers.
  [[nodiscard]] SdoAbortCode write_resolved(Object& obj, SubObject& sub, std::span<const std::uint8_t> bytes,
                                            Origin origin);
  // Checks an SDO/PDO access without transferring data (SDO initiate; PDO mapping).
  [[nodiscard]] SdoAbortCode check_read(std::uint16_t index, std::uint8_t sub, Origin origin = Origin::Sdo) const;
  [[nodiscard]] SdoAbortCode check_write(std::uint16_t index, std::uint8_t sub, Origin origin = Origin::Sdo) const;

  // Typed convenience for fixed-size values. get() returns 0 for a missing entry.
  template <class T>
  [[nodiscard]] T get(std::uint16_t index, std::uint8_t sub) const {
    return value_as<T>(find(index, sub));
  }
  // set() encodes into a stack buffer: an application updating its inputs (the TPDO path) does
  // not allocate.
  template <class T>
  SdoAbortCode set(std::uint16_t index, std::uint8_t sub, T v, Origin origin = Origin::Local) {
    static_assert(std::is_arithmetic_v<T> && sizeof(T) <= 8);
    const SubObject* s = find(index, sub);
    if (s == nullptr) return write(index, sub, {}, origin);  // reports the right "does not exist" code
    std::array<std::uint8_t, 8> buf{};
    if constexpr (std::is_floating_point_v<T>) {
      std::memcpy(buf.data(), &v, sizeof(T));  // x86/ARM Linux targets are little endian
      return write(index, sub, std::span<const std::uint8_t>(buf.data(), sizeof(T)), origin);
    } else {
      const std::size_t width = s->value.size();
      if (width > buf.size()) return write(index, sub, encode_width(static_cast<std::uint64_t>(v), width), origin);
      put_little_endian(static_cast<std::uint64_t>(v), std::span<std::uint8_t>(buf.data(), width));
      return write(index, sub, std::span<const std::uint8_t>(buf.data(), width), origin);
    }
  }

  // Observers are told of every committed write, whatever its origin, for as long as the returned
  // Subscription lives. A service keeps it as a member so that destroying the service
  // unregisters the observer (the dictionary may outlive it, e.g. a Node rebuilt on it).
  Subscription add_observer(ChangeObserver obs);
  [[nodiscard]] std::size_t observer_count() const { return observers_->size(); }

  // Sets every sub-object whose index is in [first, last] back to its default (1011h restore,
  // NMT reset communication / reset application). Does not run hooks.
  void reset_to_defaults(std::uint16_t first, std::uint16_t last);

  // The values that differ from their defaults, and a fingerprint of the layout (indices,
  // sub-indices, types). import_values() refuses another layout or a value its entry cannot hold
  // (StateError, nothing changed); otherwise every entry gets the state's value or its default.
  // Like a stored-parameter load it runs no hooks and tells no observer: the services reload().
  void export_values(StateWriter& w) const;
  void import_values(const StateReader& r);
  [[nodiscard]] std::uint64_t layout_fingerprint() const;

 private:
  // A fixed-size value read from its little-endian bytes; 0 for a missing entry (nullptr).
  template <class T>
  [[nodiscard]] static T value_as(const SubObject* s) {
    T v{};
    if (s != nullptr) std::memcpy(&v, s->value.data(), std::min(sizeof(T), s->value.size()));
    return v;
  }

  std::map<std::uint16_t, Object> objects_;
  // objects_ by index, for find(): one hashed look-up instead of a walk down the tree, which the
  // translation of every frame makes several of (its nodes are map nodes: their addresses stay
  // while the object does). Kept by the builders and remove() alone.
  std::unordered_map<std::uint16_t, Object*> index_;
  std::uint64_t layout_ = 0;
  std::shared_ptr<detail::CallbackList<ChangeObserver>> observers_;
};

}  // namespace oegw::canopen
