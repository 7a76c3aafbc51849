// One sub-device's boot steps, steps 3 to 5 of the network manager's boot (network_manager.hpp):
// the identity check (1000h, 1018h:01..04 against the configuration and the driver, CiA 302-2),
// the diagnostics (1008h/1009h/100Ah, 1001h), the driver's boot reads, then the writes — producer
// heartbeat (1017h), the driver's configuration, the mapping file's `sdo` list — and what each SDO
// answer means for them. Boot apart from the network's watch, as CiA 302-2 separates the boot-up
// of one slave from the network's management: no I/O and no time here; the network manager sends
// each request, holds it while a heartbeat is late, and applies the verdict.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "canopen/types.hpp"
#include "subdevices/driver.hpp"

namespace oegw::subdevices {

struct NodeSettings {
  std::string name;  // "right_grip"
  NodeId node{};
  std::uint16_t heartbeat_ms = 100;        // written to the node's 1017h (0: not written, not watched)
  std::uint16_t heartbeat_timeout_ms = 0;  // consumer time; 0 = 1.5 × heartbeat_ms (CiA 302 practice)
  std::uint16_t pdo_timeout_ms = 0;        // freshness deadline of every PDO-carried input; 0 = derived
  bool mandatory = false;
  ExpectedIdentity identity;  // checked besides the driver's own expectations
  // 1018h:03: false compares only the major revision (upper 16 bits, CiA 301 §7.5.2.13: a
  // minor revision is a compatible firmware update); true compares all 32 bits.
  bool exact_revision = false;
  std::vector<SdoWrite> sdo;  // written after the driver's configuration
};

// What a node said about itself at its last boot (CiA 301 §7.5.2: 1018h identity, 1008h/1009h/
// 100Ah VISIBLE_STRINGs, 1001h error register), read during configuration and kept until the
// next boot. A value the node does not have (the read was aborted) is nullopt.
struct NodeDiagnostics {
  std::optional<std::uint32_t> device_type;                                // 1000h
  std::optional<std::uint32_t> vendor_id, product_code, revision, serial;  // 1018h:01..04
  std::optional<std::string> device_name;                                  // 1008h
  std::optional<std::string> hardware_version;                             // 1009h
  std::optional<std::string> software_version;                             // 100Ah
  std::optional<std::uint8_t> error_register;                              // 1001h
  // Longest string kept (longer ones are cut); non-printable characters become '?'.
  static constexpr std::size_t kMaxText = 32;
  // "vendor 000000B4h, product 00000001h, revision 00010003h, serial -, name \"JST\", hardware
  // \"0.00\", software \"0.00\", error register 00h" (- for what is not present).
  [[nodiscard]] std::string describe() const;
};

class NodeBoot {
 public:
  struct Step {
    // DriverReads: ask the driver; Diagnostics: report what was read (on_diagnostics);
    // DriverWrites: the driver's configuration(), asked after its boot reads (it may depend on
    // what they found, e.g. the generic node's analogue inputs mapped).
    enum class Kind : std::uint8_t { Read, Write, DriverReads, Diagnostics, DriverWrites };
    Kind kind = Kind::Read;
    std::uint16_t index = 0;
    std::uint8_t sub = 0;
    std::vector<std::uint8_t> data;
    std::string what;
    // For reads: checks the answer; returns an error text, or empty when fine.
    std::function<std::string(const std::vector<std::uint8_t>&)> check;
    bool driver_read = false;   // a read the driver asked for: aborts go to on_boot_read_abort
    bool driver_write = false;  // a write of the driver's configuration(): aborts go to instead_of_refused
    bool optional = false;      // an abort means "not present": on to the next step
  };
  // What advance() found next.
  enum class Next : std::uint8_t {
    Request,      // current() is a read or a write to send
    Diagnostics,  // the diagnostics are read: report them, then check_error_register()
    Done,         // every step done: the node is configured
  };
  // What an answer means.
  struct Verdict {
    enum class Kind : std::uint8_t {
      Continue,  // on to advance()
      NoAnswer,  // an SDO time-out: the node is missing
      Refused,   // an abort or a wrong value: the node is refused
    };
    Kind kind = Kind::Continue;
    std::string why;  // NoAnswer, Refused: "reading 1018h:01 (vendor-ID): ..."
  };

  NodeBoot() = default;
  // The steps' checks keep what they read in this object: it stays where it is.
  NodeBoot(const NodeBoot&) = delete;
  NodeBoot& operator=(const NodeBoot&) = delete;

  // Starts a boot over: the diagnostics cleared, the steps listed for `settings` and `driver`
  // (whose begin_boot() is called), the first one current. `driver` outlives the boot.
  void plan(const NodeSettings& settings, Driver& driver);
  // Passes the markers up to the next request, asking the driver for its reads and its
  // configuration when they come up.
  [[nodiscard]] Next advance();
  // The request advance() found (Next::Request).
  [[nodiscard]] const Step& current() const { return steps_[next_]; }
  // The answer to current(): SdoAbortCode::None with the data read, or the abort code.
  [[nodiscard]] Verdict on_answer(canopen::SdoAbortCode code, const std::vector<std::uint8_t>& data);
  // After Next::Diagnostics: the driver's refusal of the 1001h answer, as it came ("" when it
  // takes it, or when the node has no 1001h: the driver then reads it itself).
  [[nodiscard]] std::string check_error_register();

  [[nodiscard]] const NodeDiagnostics& diagnostics() const { return diag_; }
  // What an earlier boot read, given back (a run-time state's import): no boot is under way.
  void restore_diagnostics(NodeDiagnostics d) { diag_ = std::move(d); }
  // The writes of this boot (Driver::apply_boot_writes: the event timers actually written).
  [[nodiscard]] std::vector<SdoWrite> writes() const;

 private:
  void add_identity_steps(const NodeSettings& settings);  // 1000h, 1018h:01..04 (checked and kept)
  void add_diagnostic_steps();                            // 1008h, 1009h, 100Ah, 1001h (kept)

  Driver* driver_ = nullptr;
  std::vector<Step> steps_;
  std::size_t next_ = 0;
  NodeDiagnostics diag_;  // read at the last boot
  // 1001h as the node answered it (1 byte, CiA 301; 2 bytes, the Novotechnik's UNSIGNED16),
  // handed to the driver as it came.
  std::vector<std::uint8_t> error_register_answer_;
};

}  // namespace oegw::subdevices
