// The upstream CiA 852 device ("OE interface module"): the object dictionary of the configured
// functional elements (FE), their default PDOs, and the behaviour CiA 852 adds to CiA 301/401.
//
// What build_oe_dictionary() creates (CiA 852 clauses 9, 11, 12; only what the configured FEs need):
//  * 6000h "Read input 8-bit" UNSIGNED8 ro mappable: joystick n memory (sub 2n−1) and buttons
//    (sub 2n), pedal n memory (sub 20h+n), push-button cluster n (subs 31h+8(n−1) … 38h+8(n−1)).
//  * 6401h "Read analogue input 16-bit" INTEGER16 ro mappable: joystick n x/y/z (subs 3n−2 … 3n),
//    pedal n (sub 30h+n), wheel n (sub 40h+n).
//  * 6120h "Read input 32-bit" INTEGER32 ro mappable: encoder n (sub 80h+n).
//  * 6423h "Analogue input global interrupt enable" BOOLEAN rw, default FALSE: present when an
//    FE with analogue inputs (joystick, pedal, wheel) is configured (Tables 1, 2, 4).
//  * 6200h "Write output 8-bit" UNSIGNED8 rw mappable, 6206h "Error mode output 8-bit" UNSIGNED8
//    rw default 01h, 6207h "Error value output 8-bit" UNSIGNED8 rw default 0: indicator cluster n
//    (subs 01h+8(n−1) … 08h+8(n−1)).
//  * 6411h "Write analogue output 16-bit" INTEGER16 rw mappable, 6443h "Analogue output error
//    mode" UNSIGNED8 rw default 01h, 6444h "Analogue output error value integer" INTEGER32 rw
//    default 0 (INTEGER32 as CiA 401 defines 6444h): display n parameter p (sub 12(n−1)+p).
//  Sub-index layout: mapping/functional_elements.hpp. The ARRAYs hold only the sub-indexes of
//  the configured instances (gaps allowed: a missing sub answers SDO abort 0609 0011h); sub 0 is
//  the highest sub-index present (CiA 301 §7.4.3), so its value is not the number of entries.
//  * 1000h per Table 8 (device_type_for()), 1016h (host heartbeat consumer, one entry) when an
//    output FE exists (§8.3, Annex A), everything else of CiA 301 from canopen::Node.
//  * PDOs of clause 12 (all disabled, transmission type FFh, inhibit 0, event timer 0):
//      TPDO 1, 5..19   joystick 1, 2..16: 6401 x,y,z (10h), 6000 memory, buttons (08h)
//      TPDO 20..27     pedals 2k+1, 2k+2 (k = 0..7): 6000 memory, 6401 position per pedal
//      TPDO 28..31     encoders 2k+1, 2k+2: 6120 position (20h)
//      TPDO 32, 33     wheels 1..4, 5..8: 6401 position
//      TPDO 34..41     push-button cluster 1..8: its eight 6000h bytes
//      RPDO 1, 5..11   indicator cluster 1, 2..8: its eight 6200h bytes
//      RPDO 2, 4, 12   display 1 parameters 1–4, 5–8, 9–12
//      RPDO 13..33     display d (2..8): RPDOs 13+3(d−2) … 15+3(d−2), 4 parameters each
//    A PDO exists when one of its FEs is configured; it maps only the configured FEs' entries
//    (in the clause 12 order). COB-IDs: TPDO 1 = 8000 0180h + node-ID (Table 10), every other
//    PDO 8000 0000h (Tables 14, 18, 22, 26, 30, 34; §12.2.2) — the host assigns them.
//
// Decisions on CiA 852 where the text is open or inconsistent (this list is their record):
//  * Table 8 bit positions: specific functionality = bits 24–31, M = bit 23, I/O functionality
//    = bits 16–19 (bit 16 digital input, 17 digital output, 18 analogue input, 19 analogue
//    output), profile 0191h = bits 0–15. "0" in a row means "this FE does not set the bit".
//    A joystick sets the digital-input bit only when it has buttons ("Joystick with buttons");
//    memory bits alone do not, as for the foot pedal whose row never sets it.
//  * The joystick dictionary layout is fixed (3 axes, memory and buttons bytes always exist):
//    TPDO 1 sub 4/5 (6000h) are mandatory and fixed byte positions help the host. A joystick
//    without buttons is declared in OeDeviceConfig::joysticks_without_buttons (1000h only).
//  * RPDO 13–34 for displays 2–8 (22 PDOs for 21 needed): three each, RPDO 34 unused.
//  * Encoder mapping entries are printed without length (6120 81h): 20h (INTEGER32) is used.
//  * 6423h (CiA 401: analogue inputs raise no "interrupt" when FALSE): while FALSE, set_input of
//    a 6401h field updates the dictionary without an event — SDO reads and every TPDO sent for
//    another reason (a button, the event timer, SYNC) carry the current value, but an axis
//    change alone sends nothing. 6120h (a digital input in CiA 401) is not affected.
//  * §8.6 EMCY 0080h: raised with error register 01h (generic only: §11.3 forbids the
//    profile-specific bit) each time the node enters operational with 6423h FALSE and 6423h
//    exists; it stays active while operational and FALSE, and is cleared (error reset) when the
//    host sets 6423h TRUE or the node leaves operational. No NMT state change.
//  * Sub-device faults: EMCY 7000h (Table 37, "additional modules"), register bit 0 only,
//    manufacturer bytes = node-ID of the sub-device, then up to 4 ASCII bytes of its name. A
//    second fault while 7000h is active is reported by an extra 7000h frame (the EMCY producer
//    records one active 7000h); a sub-device recovering while others are still faulty sends
//    EMCY 0000h naming it, with the remaining error register; the last one clears 7000h.
//  * TPDO numbers follow CiA 301 (TPDO n = 1800h/1A00h + n − 1), as Table 9 (TPDO 1 = 1800h)
//    and the RPDO tables (RPDO 1/2 = 1400h/1401h) do; Tables 13, 17, 21, 25 print 1814h, 181Ch,
//    1820h, 1822h for TPDO 20, 28, 32, 34 (1800h + n), which contradicts both. The clause
//    headings, the text and the PDO numbers win: pedal 1 is TPDO 20 at 1813h.
//  * Pedal pairs (Table 16 maps pedal 2's entries into TPDO 20): a PDO maps only the configured
//    pedals of its pair, encoders and wheels likewise.
//  * Table 12 sub 3 ("FFFFh if 3-axis joystick not supported") is not applied: z always exists
//    (0 when not fed), so the PDO layout does not depend on the axis count.
//  * Tables 32/36 give RPDO mapping sub 0 the access "const", §8.5 makes variable mapping
//    mandatory: every mapping sub 0 is rw (the core's CiA 301 mapping procedure). The
//    communication records' sub 0 is const (Tables 10, 14, ...).
//  * TPDO COB-IDs use the "8000 …h" form (RTR allowed: the core serves RTR for types 252/253).
//  * Annex A: 1028h (EMCY consumer) exists when outputs exist, consuming 81h..FFh except the
//    device's own EMCY (that entry keeps the configured node-ID across an LSS change); received
//    EMCYs go to on_emcy().
//  * Outputs: 6444h is INTEGER32 (CiA 401); an error value outside INTEGER16 is clamped when
//    applied to 6411h. Output values restored from the store (1010h) or by an NMT reset are
//    reported through on_output.
//  * Output FEs the mapping file gives to DDS/LCM only (`sources` without canopen;
//    OeDeviceConfig::host_may_not_command): a host SDO download of their 6200h/6411h entries is
//    aborted with 0800 0021h, the CiA 301 code for "cannot be transferred because of local
//    control"; their bytes in an RPDO are ignored while the RPDO's other entries apply (CiA 301
//    has no error for one refused entry). 6206h/6207h and 6443h/6444h stay writable, and the
//    error values apply to these FEs too on a host heartbeat loss. CiA 401 resets still apply:
//    an NMT reset node puts them back to their default (or stored) values, and 1010h "save"
//    stores their current values, whoever wrote them.
//  * Host heartbeat loss: reported by the Node's heartbeat consumer (Node::on_heartbeat_timeout,
//    after its EMCY 8130h), on whichever path notices it, or called directly by the gateway.
//  * NMT reset node / reset communication from the host: the inputs keep their current values
//    (6000h/6401h/6120h are written back after the reset restored their defaults), 1001h keeps
//    the active errors, and every sub-device still faulty is reported again with EMCY 7000h
//    right after the boot-up.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "canopen/node.hpp"
#include "gateway/fe_model.hpp"
#include "mapping/functional_elements.hpp"

namespace oegw::gateway {

struct OeIdentity {
  std::uint32_t vendor = 0;
  std::uint32_t product = 0;
  std::uint32_t revision = 0;
  std::uint32_t serial = 0;
};

struct OeDeviceConfig {
  canopen::NodeId node_id{0x20};
  OeIdentity identity{};
  std::string device_name = "oegw OE interface module";
  std::string hardware_version = "1";
  std::string software_version = "0.1.0";
  std::uint16_t heartbeat_ms = 1000;     // 1017h default (mandatory, Annex A)
  std::uint16_t host_node = 0;           // 1016h:01 default host node-ID (0: entry unused)
  std::uint16_t host_heartbeat_ms = 0;   // 1016h:01 default consumer time
  std::vector<mapping::FeId> fes;
  std::set<mapping::FeId> joysticks_without_buttons;  // affects 1000h only (Table 8)
  // Output FEs the host may not command (their mapping-file `sources` leave out canopen): an SDO
  // download of their 6200h/6411h entries is aborted with 0800 0021h ("cannot be transferred
  // because of local control", CiA 301 Table 22) and their bytes in an RPDO are ignored. Writes
  // of the gateway itself (Origin::Local: DDS/LCM commands, 6206h/6443h error values) pass.
  std::set<mapping::FeId> host_may_not_command;
  std::filesystem::path store_path;      // empty: no 1010h/1011h
};

// CiA 852 §11.2 Table 8.
inline constexpr std::uint16_t kProfile401 = 0x0191;
[[nodiscard]] std::uint32_t device_type_for(const std::vector<mapping::FeId>& fes,
                                            const std::set<mapping::FeId>& joysticks_without_buttons = {});

// One PDO of clause 12 for this FE set.
struct OePdo {
  bool transmit = true;
  std::uint16_t number = 0;
  canopen::PdoParameters params;
};
[[nodiscard]] std::vector<OePdo> oe_pdos(const std::vector<mapping::FeId>& fes, canopen::NodeId node_id);

// The application objects and PDOs (not the CiA 301 objects the Node adds). Returns the
// NodeConfig to construct the Node with (1000h, identity, 1016h ...).
canopen::NodeConfig build_oe_dictionary(const OeDeviceConfig& cfg, canopen::ObjectDictionary& od);

class OeDevice {
 public:
  static constexpr std::uint16_t kEmcyAnalogInputsDisabled = 0x0080;  // Table 37
  static constexpr std::uint16_t kEmcyAdditionalModules = 0x7000;     // Table 37

  OeDevice(OeDeviceConfig cfg, canopen::FrameSink sink);
  OeDevice(const OeDevice&) = delete;
  OeDevice& operator=(const OeDevice&) = delete;

  canopen::ParameterStore::LoadResult start(canopen::TimePoint now);
  bool on_frame(const canopen::CanFrame& frame, canopen::TimePoint now);
  void advance(canopen::TimePoint now);
  [[nodiscard]] std::optional<canopen::TimePoint> next_deadline() const;

  // Writes an input FE field (Origin::Local): a change sends the event-driven TPDOs mapping it.
  // One-bit fields set/clear their bit. Returns false for an unknown FE/field, an output FE or a
  // value out of the field's range (nothing written). For a device used on its own (tests); the
  // gateway mirrors its FE model instead (mirror_input).
  bool set_input(mapping::FeId fe, std::string_view field, std::int64_t value, canopen::TimePoint now);
  bool set_input(mapping::FeId fe, const mapping::FeField& field, std::int64_t value, canopen::TimePoint now);
  // The FE model's sink: one slot of an input FE changed to `value` (FeModel::slot_value: a bit
  // field as its bits, e.g. the 64 switches of a cluster). Writes the dictionary entries that
  // slot occupies (6000h bytes, 6401h, 6120h), only those that differ; the entries were looked
  // up at construction, so this neither searches nor allocates. A change sends the event-driven
  // TPDOs mapping it (at end_batch() inside a batch).
  void mirror_input(mapping::FeId fe, FeSlot slot, std::int64_t value, canopen::TimePoint now);
  // Between begin_batch() and end_batch(), input writes only update the dictionary; end_batch()
  // then sends the event-driven TPDOs once, so that a downstream frame changing several fields
  // (x, y and a button) gives one TPDO carrying all of them, not one per field.
  void begin_batch();
  void end_batch(canopen::TimePoint now);
  // Reads an FE field (inputs and outputs) from the dictionary.
  [[nodiscard]] std::optional<std::int64_t> get(mapping::FeId fe, std::string_view field) const;
  [[nodiscard]] std::optional<std::int64_t> get(mapping::FeId fe, const mapping::FeField& field) const;

  // Output FEs written by the gateway itself (Origin::Local: DDS/LCM commands the command
  // arbiter accepted). Entries that change are reported through on_output, as a host write is.
  void write_indicators(mapping::FeId fe, std::uint64_t bits);
  void write_display(mapping::FeId fe, const std::array<std::int16_t, 12>& parameters);

  // Called for every output field whose value changed (an RPDO, an SDO download, a write above,
  // the error values, an NMT reset or 1011h restore putting defaults back).
  using OutputCallback = std::function<void(mapping::FeId, FieldRef, std::int64_t value)>;
  void on_output(OutputCallback cb) { on_output_ = std::move(cb); }

  // A host write (SDO download or RPDO entry) of an output FE, before it commits: return true to
  // take it. Refused: an SDO download is aborted with 0800 0021h ("cannot be transferred because
  // of local control", CiA 301 Table 22), the FE's bytes in an RPDO are ignored. Unset: the
  // config's host_may_not_command decides.
  using HostWriteCheck = std::function<bool(mapping::FeId, canopen::Origin)>;
  void on_host_write(HostWriteCheck cb) { on_host_write_ = std::move(cb); }

  // CiA 401 6206h/6207h and 6443h/6444h: outputs whose error mode is set take their error value.
  void host_heartbeat_lost(canopen::TimePoint now);
  // The same for one output FE, or for every output FE when `only` is empty (its commander fell
  // silent: mapping-file command_timeout_ms).
  void apply_error_values(std::optional<mapping::FeId> only, canopen::TimePoint now);

  void raise_subdevice_fault(std::string_view name, canopen::NodeId node, canopen::TimePoint now);
  void clear_subdevice_fault(canopen::NodeId node, canopen::TimePoint now);
  [[nodiscard]] const std::map<std::uint8_t, std::string>& faulty_subdevices() const { return faults_; }

  // EMCY messages of other nodes (1028h, present when outputs exist).
  void on_emcy(canopen::EmcyHandler cb) { on_emcy_ = std::move(cb); }

  [[nodiscard]] canopen::Node& node() { return *node_; }
  [[nodiscard]] canopen::ObjectDictionary& od() { return od_; }
  [[nodiscard]] const OeDeviceConfig& config() const { return cfg_; }

 private:
  struct OutputRef {
    mapping::FeId fe;
    FieldRef ref;
    std::uint8_t bit;  // within the dictionary entry (6200h byte), 0xFF = whole value
  };
  // One dictionary entry an input slot occupies: the slot's value >> shift is the entry's value
  // (a bit field: one byte per entry; a whole value: shift 0).
  struct InputEntry {
    std::uint16_t index = 0;
    std::uint8_t sub = 0;
    std::uint8_t shift = 0;
    bool bits = false;
  };
  void index_inputs();
  bool write_input_entry(const InputEntry& e, std::int64_t raw);
  // node_->advance() (the Node's heartbeat time-out applies the error values, whoever calls).
  void step_node(canopen::TimePoint now);
  void watch_host_commands();
  void handle_state(canopen::NmtState s);
  void handle_od_change(std::uint16_t index, std::uint8_t sub);
  void resync_outputs();
  void after_reset();
  void report_outputs(std::uint16_t index, std::uint8_t sub, std::int64_t old_value);
  void send_emcy_frame(std::uint16_t code, const canopen::EmcyManufacturerField& msef);
  [[nodiscard]] bool analog_interrupt_enabled() const;

  OeDeviceConfig cfg_;
  canopen::FrameSink sink_;
  canopen::ObjectDictionary od_;
  std::unique_ptr<canopen::EmcyConsumer> emcy_consumer_;
  std::unique_ptr<canopen::Node> node_;
  OutputCallback on_output_;
  HostWriteCheck on_host_write_;
  std::vector<InputEntry> input_entries_;
  // kind × instance × slot → [first, first + count) in input_entries_.
  struct Span {
    std::uint16_t first = 0;
    std::uint16_t count = 0;
  };
  std::array<std::array<std::array<Span, kFeSlots>, 17>, 7> input_index_{};
  unsigned batch_depth_ = 0;
  canopen::EmcyHandler on_emcy_;
  canopen::TimePoint now_{};
  std::map<std::uint8_t, std::string> faults_;                   // node-ID -> name
  std::map<std::uint32_t, std::vector<OutputRef>> outputs_;      // index << 8 | sub -> fields
  std::map<std::uint32_t, std::int64_t> output_shadow_;          // last value of each output entry
  // Last bytes written by set_input per input entry (index << 8 | sub): an NMT reset node
  // restores the application objects to their defaults, but the inputs have not moved.
  std::map<std::uint32_t, std::vector<std::uint8_t>> input_shadow_;
  canopen::NmtState last_state_ = canopen::NmtState::Initialisation;
  canopen::Subscriptions subs_;  // last: released before the OD/Node go
};

}  // namespace oegw::gateway
