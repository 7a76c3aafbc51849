// Driver of a generic CiA 401 I/O node (pedals, third-party button clusters, indicator panels)
// described by its EDS file (CiA 306, read by eds.hpp). No vendor document: the objects are
// those of CiA 401 (generic I/O modules), as publicly known:
//   6000h  Read input 8-bit             ARRAY of UNSIGNED8, 8 digital input lines per sub-index
//   6120h  Read input 32-bit            ARRAY of UNSIGNED32, 32 digital input lines per sub-index.
//          NOTE: in CiA 401 6120h is a DIGITAL input group (the 32-bit sibling of 6000h/6100h),
//          not an analogue INTEGER32 (that is 6402h) and not an encoder (CiA 852 reuses the
//          6xxxh range differently); it is exposed as a Digital signal of 32 bits.
//   6401h  Read analogue input 16-bit   ARRAY of INTEGER16
//   6200h  Write output 8-bit           ARRAY of UNSIGNED8, 8 digital output lines per sub-index
//   6411h  Write analogue output 16-bit ARRAY of INTEGER16
//
// Signals (in this order; n = the sub-indices 1..n the EDS defines for the object):
//   in[k]     Digital  6000h:k   0..255          "bits"   one signal per input BYTE (8 lines;
//                                                         bit j = line 8(k-1)+j+1), neutral 0
//   in32[k]   Digital  6120h:k   0..4294967295   "bits"   one per 32-line group, neutral 0
//   analog[k] Analog   6401h:k   -32768..32767   "raw16"  neutral 0
//   out[k]    Output   6200h:k   0..255          "bits"   (LowLimit/HighLimit of the EDS narrow it)
//   aout[k]   Output   6411h:k   -32768..32767   "raw16"  (LowLimit/HighLimit of the EDS narrow it)
// Per byte rather than per bit: a byte is what the node maps into PDOs and what 6000h holds;
// the mapping layer picks single lines out of it.
//
// The PDO mapping is not taken from the EDS (a node may have been remapped, by its vendor or a
// previous configuration tool): it is READ FROM THE NODE at boot. The network manager runs, after
// the identity check and before NMT start:
//
//     driver.reset_mapping();                             // forget a previous boot's mapping
//     while (!(reads = driver.mapping_reads()).empty())   // what is still unknown
//       for (auto& r : reads) {                           // SDO upload r.index:r.sub, then
//         driver.apply_mapping_read(r.index, r.sub, data);        // on success, or
//         driver.apply_mapping_abort(r.index, r.sub, abort_code); // on an SDO abort
//       }
//     // driver.mapping_complete() is now true; consumed_cob_ids() lists the TPDOs in use.
//
// mapping_reads() lists, for every PDO the EDS declares (RPDO 1..4: 1400h–1403h/1600h–1603h,
// TPDO 1..4: 1800h–1803h/1A00h–1A03h), the reads not yet answered: the communication parameter's
// COB-ID (sub 1) and transmission type (sub 2) and the mapping's entry count (sub 0); once a
// count is known, its entries 1..count and, for a TPDO, its event timer (sub 5, optional: a
// refused read means none). So it is called repeatedly until it returns nothing.
// A PDO whose COB-ID has bit 31 set (not valid), or whose parameter read was aborted, is not used.
// apply_mapping_read() returns SdoAbortCode::None when the value is taken; LengthMismatch for
// data of the wrong size, SubIndexDoesNotExist for a read it did not ask for, ValueTooHigh for an
// entry count above 64, InvalidValue for a valid COB-ID on a restricted CAN-ID (CiA 301 §7.3.5:
// 000h NMT, 701h..77Fh heartbeats, the default SDO channels, ...) — then that PDO is not used
// (and on_boot_read() refuses the node, naming the ID). Until the mapping is complete the driver
// consumes no PDO (on_frame() counts unknown_cob) and set_output() sends nothing.
//
// Decoding: a TPDO frame is decoded with the mapping read back (bit offsets in mapping order,
// CiA 301 §7.2.2); entries naming other objects or dummy entries are skipped. A frame whose DLC
// differs from the mapped length is counted (wrong_length) and ignored. Each decoded signal
// becomes Valid with its value.
// Outputs: set_output() remembers the value (initially the EDS DefaultValue) and sends every
// valid RPDO that maps it, packing the remembered values of the other outputs it maps (and 0 for
// dummy/unknown entries). Returns false, sending nothing, for a non-output, a value out of range,
// or an output no valid RPDO maps.
// EMCY (CiA 301 §7.2.7.1, Table 26; CiA 401 defines no per-channel codes): 0000h clears the
// faults of every input (the value stays neutral until the next PDO); a code of a class Table 26
// defines (1000h, 2xxxh, 3xxxh, 4xxxh, 50xxh, 6xxxh, 70xxh, 8xxxh but 81xxh, 90xxh, F0xxh,
// FFxxh) faults every input (Driver::faulted) until 0000h, or until the read-back of 1001h
// "error register" (CiA 301 §7.5.2.2) at the node's next (re)start shows no error; 81xxh
// "communication" is a warning (error = false, faults nothing); any other code is counted
// (unknown_emcy) and ignored. The 1001h read-back: 00h, or only bit 4 "communication error"
// (with bit 0 "generic", which CiA 301 sets at any error), ends the faults; any other bit faults
// every input — also when no EMCY was seen (it went before the gateway listened); a refused read
// or an answer of the wrong length is no evidence (the faults stay as they are). A boot-up alone
// clears nothing: a node that rebooted may still be broken.
// Identity: 1000h DefaultValue and [DeviceInfo] VendorNumber/ProductNumber/RevisionNumber.
//
// Factory option (the table cia401_options() in cia401.cpp): eds=<path> (required). Unknown options, or an EDS that
// cannot be read or parsed, are an error carrying the parse message ("file:line: what was expected").
#pragma once

#include <array>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "canopen/306/eds_reader.hpp"
#include "subdevices/driver.hpp"

namespace oegw::subdevices {

// One SDO upload of the boot-time mapping read.
struct SdoRead {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::string what;  // for logs: "TPDO1 mapping entry 2"
};

class Cia401Driver final : public Driver {
 public:
  Cia401Driver(NodeId node, FrameSink sink, canopen::eds::File file);

  [[nodiscard]] std::string_view family() const override { return "cia401"; }
  [[nodiscard]] const std::vector<SignalInfo>& signals() const override { return signals_; }
  [[nodiscard]] ExpectedIdentity expected_identity() const override;
  // CiA 401: 6423h "analogue input global interrupt enable" (BOOLEAN, default FALSE) gates the
  // event-driven transmission of every analogue input. When the EDS has 6423h and a TPDO in use
  // (as read back at boot) maps an analogue input (6401h) with an event-driven transmission
  // type (254/255) or type 0 (acyclic synchronous: sent on change), 6423h is written TRUE;
  // otherwise nothing is written.
  [[nodiscard]] std::vector<SdoWrite> configuration() const override;

  // The boot-time mapping read (see the header comment).
  void reset_mapping();
  [[nodiscard]] std::vector<SdoRead> mapping_reads() const;
  canopen::SdoAbortCode apply_mapping_read(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data);
  void apply_mapping_abort(std::uint16_t index, std::uint8_t sub, canopen::SdoAbortCode code);
  [[nodiscard]] bool mapping_complete() const { return mapping_reads().empty(); }
  // True when a PDO in use is synchronous (transmission type 0..240, CiA 301 §7.5.2.35): the
  // node then sends (TPDO) or applies (RPDO) it only at a SYNC, which someone must produce.
  [[nodiscard]] bool needs_sync() const;

  // The Driver's boot-read hooks, run by the network manager: the mapping read above and
  // 1001h (see the header comment).
  void begin_boot() override {
    reset_mapping();
    error_register_read_ = false;
  }
  void on_application_reset(TimePoint /*now*/) override {}  // the 1001h read-back decides
  // The CiA 401 application objects 6000h..6FFFh: the inputs it decodes (with their polarity,
  // filters and interrupt masks), the outputs the gateway drives (with their polarity and error
  // modes) — a remote write of any of them changes what the FEs see or command.
  [[nodiscard]] bool protects(std::uint16_t index, std::uint8_t /*sub*/) const override {
    return index >= 0x6000 && index <= 0x6FFF;
  }
  [[nodiscard]] std::vector<std::pair<std::uint16_t, std::uint8_t>> boot_reads() const override;
  bool on_boot_read(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data,
                    std::string& error) override;
  bool on_boot_read_abort(std::uint16_t index, std::uint8_t sub, canopen::SdoAbortCode code) override;

  bool on_frame(const CanFrame& frame, TimePoint now) override;
  DecodedEmcy on_emcy(const EmcyMessage& emcy, TimePoint now) override;
  [[nodiscard]] std::vector<std::uint32_t> consumed_cob_ids() const override;
  bool set_output(std::size_t index, std::int64_t value, TimePoint now) override;

  [[nodiscard]] const canopen::eds::File& eds() const { return eds_; }

 private:
  struct Entry {
    std::uint32_t raw = 0;  // index << 16 | sub << 8 | bits
    int signal = -1;        // decoded/encoded signal, -1 = skipped
  };
  struct Pdo {
    bool transmit = false;
    std::uint16_t number = 0;  // 1..4
    std::optional<std::uint32_t> cob_id;
    std::optional<std::uint8_t> transmission_type;
    std::optional<std::uint16_t> event_timer;  // TPDO 18xxh:05 as read (none: absent)
    bool event_timer_done = false;             // TPDO: read or refused
    std::optional<std::uint8_t> count;
    std::vector<std::optional<std::uint32_t>> entries;
    bool failed = false;  // a read was aborted or refused: the PDO is not used
    // Built when complete:
    std::vector<Entry> decoded;
    unsigned bits = 0;
    [[nodiscard]] bool complete() const;
    [[nodiscard]] bool usable() const;
    [[nodiscard]] std::uint16_t comm_index() const {
      return static_cast<std::uint16_t>((transmit ? 0x1800 : 0x1400) + number - 1);
    }
    [[nodiscard]] std::uint16_t map_index() const {
      return static_cast<std::uint16_t>((transmit ? 0x1A00 : 0x1600) + number - 1);
    }
  };

  // Each usable TPDO read back at boot, with the event timer and type read from the node (the
  // mapping file's `sdo` writes, made after the reads, replace them).
  void refresh_carriers() override;

 public:
  // Before a boot has read the node's PDOs: the EDS's default TPDOs (valid COB-ID, mapping
  // length, type, inhibit time, event timer), with `writes` applied; after one: the base's.
  [[nodiscard]] std::vector<TpdoTraffic> expected_tpdos(const std::vector<SdoWrite>& writes) const override;

 private:
  void flush_outputs(TimePoint now) override;
  void export_family_state(canopen::StateWriter& w) const override;
  void import_boot_learned(const canopen::StateReader& r) override;
  void import_family_state(const canopen::StateReader& r) override;
  void add_signals(std::uint16_t index, const char* prefix, SignalKind kind, std::int64_t min, std::int64_t max,
                   const char* unit);
  Pdo* find_pdo(std::uint16_t index);
  void on_error_register(std::span<const std::uint8_t> data);
  bool error_register_read_ = false;  // 1001h answered or refused in this boot
  void build(Pdo& p);
  [[nodiscard]] int signal_for(std::uint32_t entry) const;

  canopen::eds::File eds_;
  std::vector<SignalInfo> signals_;
  std::map<std::uint32_t, std::size_t> by_object_;  // index << 8 | sub -> signal
  std::vector<std::uint8_t> width_;                 // bits of each signal's object
  std::vector<std::int64_t> outputs_;               // remembered output values, by signal
  std::vector<Pdo> pdos_;
  std::vector<std::size_t> pending_;  // RPDOs (pdos_ index) to send at flush_outputs()
};

// Family factory (families.hpp): options "eds" = path to the node's EDS file.
std::unique_ptr<Driver> make_cia401_driver(NodeId node, FrameSink sink, const DriverOptions& options,
                                           std::string& error);

}  // namespace oegw::subdevices
