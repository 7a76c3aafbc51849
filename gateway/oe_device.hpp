// The upstream CiA 852 device ("OE interface module") at run time: the behaviour CiA 852 adds to
// CiA 301/401 on the dictionary of the configured functional elements (FE). The dictionary, its
// default PDOs and 1000h are built by profiles/cia852/ (dictionary.hpp, pdo_defaults.hpp,
// device_type.hpp).
//
// Decisions on CiA 852 where the text is open or inconsistent (this list is their record; those
// on PDOs — which exist, their layouts, the instances not configured, 6423h and the TPDOs — are
// in docs/design/cia852-decisions.md):
//  * 6423h FALSE: an axis change (6401h) updates the dictionary without a TPDO event; TPDOs sent
//    for another reason carry it (docs/design/cia852-decisions.md).
//  * §8.6 EMCY 0080h: raised with error register 01h (generic only: §11.3 forbids the
//    profile-specific bit) each time the node enters operational with 6423h FALSE and 6423h
//    exists; it stays active while operational and FALSE, and is cleared (error reset) when the
//    host sets 6423h TRUE or the node leaves operational. No NMT state change.
//  * Every EMCY the device sends goes through its Node's EMCY producer (canopen/301/emcy.hpp):
//    1015h inhibit time and its queue, 1003h history, byte 2 = 1001h, 1014h bit 31 = none sent.
//  * Sub-device faults: EMCY 7000h (Table 37, "additional modules"), register bit 0 only,
//    manufacturer bytes = node-ID of the sub-device, then up to 4 ASCII bytes of its name;
//    1003h entry 7000h | node-ID << 16. A second fault while 7000h is active is reported by an
//    extra 7000h frame, an event EMCY of the producer (EmcyProducer::report: 1015h and 1003h
//    apply, 1001h unchanged; the producer holds one active 7000h); a sub-device recovering while
//    others are still faulty sends EMCY 0000h naming it (an event too, not in 1003h), with the
//    remaining error register; the last one clears 7000h.
//  * Remote EMCY (CiA 302-7 multi-level networking: the host diagnoses the sub-layered network
//    through the gateway; CiA 852 §5.2, §8.7): forward_subdevice_emcy() passes a sub-device's
//    EMCY on as an event EMCY of this device:
//        byte 0..1  the sub-device's own error code (0000h error reset included)
//        byte 2     this device's 1001h (CiA 301 §7.2.7.3: byte 2 is the producer's error
//                   register; the forward leaves it unchanged)
//        byte 3     the sub-device's node-ID (1..127)
//        byte 4     the sub-device's error register (its byte 2)
//        byte 5..7  the sub-device's manufacturer-specific bytes 0..2 (its bytes 3..5); its
//                   bytes 3..4 (frame bytes 6..7) do not fit and are lost
//    1003h entry: code | node-ID << 16 (none for 0000h). CiA 301 and CiA 302-7 define no frame
//    for a forwarded EMCY (302-7 names the service only); this layout is the gateway's own. A
//    host tells a forward by byte 3, the sub-device's node-ID (never 0): the gateway's own EMCYs
//    carry 0 there, except 7000h and the 0000h naming a recovered sub-device (node-ID, then
//    name characters in bytes 4..7), which a forwarded 7000h or 0000h of that node resembles.
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
//  * Bit rate (docs/guides/commission.md#bit-rate): LSS configure bit timing takes the rates of
//    OeDeviceConfig::supported_bit_timings, which the EDS lists (gateway/runtime_config.hpp
//    upstream_bit_timings: one list); LSS activate bit timing calls on_bit_rate_switch at the
//    switch (canopen/node.hpp: silent for the switch delay, switch, silent again), where the
//    program sets the upstream interface.
//  * NMT reset node / reset communication from the host: the inputs keep their current values
//    (6000h/6401h/6120h are written back after the reset restored their defaults), 1001h keeps
//    the active errors, and every sub-device still faulty is reported again with EMCY 7000h
//    right after the boot-up.
#pragma once

#include <array>
#include <cstddef>
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
#include "mapping/fe_names.hpp"
#include "profiles/cia852/dictionary.hpp"

namespace oegw::gateway {

// The device is configured as its dictionary is (profiles/cia852/dictionary.hpp).
using OeIdentity = cia852::Identity;
using OeDeviceConfig = cia852::DeviceConfig;

// The longest text a run-time state of the gateway carries (a sub-device's why and fault, its
// name): the refusals a boot gives (every boot write named) run to some hundred bytes and the
// mapping file does not limit a name; the bound only keeps a damaged state from taking the
// memory.
inline constexpr std::size_t kMaxStateText = 64 * 1024;

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
  void write_indicators(mapping::FeId fe, std::uint64_t bits, canopen::TimePoint now);
  void write_display(mapping::FeId fe, const std::array<std::int16_t, 12>& parameters, canopen::TimePoint now);

  // Called for every output field whose value changed (an RPDO, an SDO download, a write above,
  // the error values, an NMT reset or 1011h restore putting defaults back), with the time of the
  // call that changed it.
  using OutputCallback = std::function<void(mapping::FeId, FieldRef, std::int64_t value, canopen::TimePoint now)>;
  void on_output(OutputCallback cb) { on_output_ = std::move(cb); }
  // Every output field's current value through on_output, changed or not (a gateway taking the
  // device over at a reload: its FE model and output bindings start from what the host sees).
  void announce_outputs(canopen::TimePoint now);

  // A host write (SDO download or RPDO entry) of an output FE, before it commits: return true to
  // take it. Refused: an SDO download is aborted with 0800 0021h ("cannot be transferred because
  // of local control", CiA 301 Table 22), the FE's bytes in an RPDO are ignored. Unset: the
  // config's host_may_not_command decides. `now`: the time of the host's frame.
  using HostWriteCheck = std::function<bool(mapping::FeId, canopen::Origin, canopen::TimePoint now)>;
  void on_host_write(HostWriteCheck cb) { on_host_write_ = std::move(cb); }

  // CiA 401 6206h/6207h and 6443h/6444h: outputs whose error mode is set take their error value.
  void host_heartbeat_lost(canopen::TimePoint now);
  // The same for one output FE, or for every output FE when `only` is empty (its commander fell
  // silent: mapping-file command_timeout_ms).
  void apply_error_values(std::optional<mapping::FeId> only, canopen::TimePoint now);

  void raise_subdevice_fault(std::string_view name, canopen::NodeId node, canopen::TimePoint now);
  void clear_subdevice_fault(canopen::NodeId node, canopen::TimePoint now);
  // A sub-device's EMCY passed upstream as this device's (remote EMCY, the layout above).
  // Returns false when the producer could not send it (1014h bit 31, inhibit queue full); in
  // Stopped, the Node holds every EMCY back.
  bool forward_subdevice_emcy(const canopen::EmcyMessage& emcy, canopen::TimePoint now);
  // The manufacturer bytes of a forwarded EMCY: [node-ID, register, its msef 0..2].
  [[nodiscard]] static canopen::EmcyManufacturerField forwarded_msef(const canopen::EmcyMessage& emcy);
  [[nodiscard]] const std::map<std::uint8_t, std::string>& faulty_subdevices() const { return faults_; }

  // EMCY messages of other nodes (1028h, present when outputs exist).
  void on_emcy(canopen::EmcyHandler cb) { on_emcy_ = std::move(cb); }
  // Every frame the device sends, before it goes to its sink (the black box, gateway_tap.hpp).
  void on_sent(std::function<void(const canopen::CanFrame&)> cb) { sent_ = std::move(cb); }

  // LSS activate bit timing, at the switch: the upstream interface must now run at `bit_per_s`.
  using BitRateSwitch = std::function<void(std::uint32_t bit_per_s)>;
  void on_bit_rate_switch(BitRateSwitch cb) { on_bit_rate_switch_ = std::move(cb); }

  [[nodiscard]] canopen::Node& node() { return *node_; }
  [[nodiscard]] const canopen::Node& node() const { return *node_; }

  // Why no run-time state can be taken now ("" when it can): a host's SDO transfer under way.
  [[nodiscard]] std::string busy() const;
  // Run-time state (canopen/state.hpp): the Node's (dictionary and services), the sub-devices
  // reported faulty (7000h), the outputs and inputs as last written, the last NMT state. The
  // import takes the place of start(): nothing is sent, no callback is called.
  void export_state(canopen::StateWriter& w) const;
  void import_state(const canopen::StateReader& r);
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
  // Its dictionary entry and its input_shadow_ entry are looked up at its first write, not at
  // every one: an axis changes with nearly every frame.
  struct InputEntry {
    canopen::ObjectDictionary::Slot slot;
    std::uint8_t shift = 0;
    bool bits = false;
    std::vector<std::uint8_t>* shadow = nullptr;  // in input_shadow_ (a map node: it stays)
  };
  void index_inputs();
  bool write_input_entry(InputEntry& e, std::int64_t raw);
  [[nodiscard]] std::vector<std::uint8_t>& shadow_of(InputEntry& e);
  // node_->advance() (the Node's heartbeat time-out applies the error values, whoever calls).
  void step_node(canopen::TimePoint now);
  void watch_host_commands();
  void handle_state(canopen::NmtState s);
  void handle_od_change(std::uint16_t index, std::uint8_t sub);
  void resync_outputs();
  void after_reset();
  void report_outputs(std::uint16_t index, std::uint8_t sub, std::int64_t old_value);
  // 6423h (CiA 401 analogue input global interrupt enable): nullopt when the device has none.
  [[nodiscard]] std::optional<bool> analog_interrupts_enabled();

  OeDeviceConfig cfg_;
  std::function<void(const canopen::CanFrame&)> sent_;
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
  BitRateSwitch on_bit_rate_switch_;
  canopen::TimePoint now_{};
  std::map<std::uint8_t, std::string> faults_;               // node-ID -> name
  std::map<std::uint32_t, std::vector<OutputRef>> outputs_;  // index << 8 | sub -> fields
  std::map<std::uint32_t, std::int64_t> output_shadow_;      // last value of each output entry
  // Last bytes written by set_input per input entry (index << 8 | sub): an NMT reset node
  // restores the application objects to their defaults, but the inputs have not moved.
  std::map<std::uint32_t, std::vector<std::uint8_t>> input_shadow_;
  canopen::ObjectDictionary::Slot interrupt_enable_{cia401::kAnalogueInputGlobalInterruptEnable, 0};  // 6423h
  canopen::NmtState last_state_ = canopen::NmtState::Initialisation;
  canopen::Subscriptions subs_;  // last: released before the OD/Node go
};

}  // namespace oegw::gateway
