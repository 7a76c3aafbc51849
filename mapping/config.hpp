// The mapping file: the engineer's one configuration file (docs/reference/mapping-file.md documents
// every key). load_config() parses (yaml-cpp) and validates; it returns either a complete Config or
// every error found, each as "file:line:column: what was found; expected what" (1-based).
// Nothing is half-built: a Config exists only when there is no error.
//
// Sub-device signals are checked against a SignalCatalogue the caller injects (the gateway
// passes one built on the driver factory; tests pass a fake one), so this layer never creates
// a driver.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mapping/fe_names.hpp"
#include "mapping/translate.hpp"
#include "subdevices/driver.hpp"
#include "subdevices/driver_options.hpp"
#include "subdevices/network_manager.hpp"
#include "subdevices/signal.hpp"

namespace oegw::mapping {

// Where a node was found in the file (1-based line and column).
struct Location {
  std::string file;
  int line = 0;
  int column = 0;
  [[nodiscard]] std::string str() const;          // "file:line:column"
  [[nodiscard]] std::string line_column() const;  // "line 5, column 3"
};

struct Diagnostic {
  Location where;
  std::string message;                    // "what was found; expected what"
  [[nodiscard]] std::string str() const;  // "file:line:column: message"
};

// Returns the signals a driver family provides with these options, or nullopt and every refusal
// (unknown family, options the family refuses), each naming its option where it is about one
// (subdevices/driver_options.hpp), so that each is reported at that option's value.
using SignalCatalogue = std::function<std::optional<std::vector<subdevices::SignalInfo>>(
    std::string_view family, const subdevices::DriverOptions& options, subdevices::OptionRefusals& refusals)>;

struct UpstreamIdentity {  // 1018h sub-indices 1..4
  std::uint32_t vendor_id = 0;
  std::uint32_t product_code = 0;
  std::uint32_t revision = 0;
  std::uint32_t serial = 0;
};

// One additional SDO server channel of the gateway (`upstream.sdo_servers`): the k-th entry
// (1-based) is 1200h + k (CiA 301 §7.5.2.33). With `subdevice` the channel is bound to that
// sub-device (its requests go to the sub-device's dictionary); without, it serves the gateway's
// own dictionary. Without request/response the channel is disabled (COB-IDs 8000 0000h) until
// the host writes 1200h+k:01/02.
struct SdoServerConfig {
  std::string subdevice;                                    // the bound sub-device's name; empty: not bound
  std::optional<std::uint32_t> request;                     // COB-ID client -> server (1200h+k:01), 11-bit
  std::optional<std::uint32_t> response;                    // COB-ID server -> client (1200h+k:02), 11-bit
  Location where;                                           // the list entry
  Location subdevice_where, request_where, response_where;  // the values, when written
  [[nodiscard]] bool enabled() const { return request.has_value() && response.has_value(); }
};

struct UpstreamConfig {
  std::string interface = "can0";
  std::uint8_t node_id = 0;  // required
  std::uint32_t bitrate = 250000;
  UpstreamIdentity identity;
  // 1017h producer heartbeat time at power-on. CiA 852 §8.3: heartbeat "shall be used", so the
  // default is 100 ms
  // (docs/reference/mapping-file.md#upstreamheartbeat_ms-and-upstreamidentityserial); 0 (off) only
  // when written, and `oegw check` warns.
  std::uint16_t heartbeat_ms = 100;
  std::string store = "/var/lib/oegw/upstream.store";  // 1010h/1011h store
  // The network ID of the host's bus (CiA 302-7 multi-level networking: the number the host uses
  // to name a network in a remote SDO/EMCY), 1..127, distinct from downstream.network_id.
  std::uint8_t network_id = 1;
  std::vector<SdoServerConfig> sdo_servers;  // 1201h, 1202h, ... (at most 127)
  Location where;
  Location network_id_where;              // the `network_id` value, when written
  Location interface_where, store_where;  // the values, when written
};

// Which sub-device EMCYs the gateway passes upstream as its own (remote EMCY, CiA 302-7;
// gateway/oe_device.hpp gives the frame): every one; the errors (those the driver decodes as
// an error, DecodedEmcy::error) and the error resets 0000h; none. Whatever is chosen, the fault
// policy's EMCY 7000h naming a faulty sub-device goes up.
enum class EmcyForwarding : std::uint8_t { All, Faults, None };
[[nodiscard]] constexpr std::string_view to_string(EmcyForwarding f) {
  switch (f) {
    case EmcyForwarding::All: return "all";
    case EmcyForwarding::Faults: return "faults";
    case EmcyForwarding::None: return "none";
  }
  return "?";
}

struct DownstreamConfig {
  std::string interface = "can1";
  std::uint32_t bitrate = 250000;
  std::uint8_t network_id = 2;  // the sub-devices' network (see UpstreamConfig::network_id)
  EmcyForwarding emcy_forwarding = EmcyForwarding::All;
  // The gateway's SDO client time-out toward every sub-device (its boot and configuration, and
  // the host's remote SDO: a host must wait longer than this for the gateway's 0504 0000h).
  std::uint16_t sdo_timeout_ms = 1000;
  // The SYNC the gateway produces downstream (CiA 301 §7.2.5, COB-ID 080h, no counter), for the
  // sub-devices' synchronous TPDOs (transmission types 1..240: one after every n-th SYNC);
  // 0: no SYNC (then a node configured with a synchronous type is refused, see
  // sections::check_sync).
  std::uint16_t sync_period_ms = 0;
  Location where;
  Location sync_period_where;  // the `sync_period_ms` value, when written
  Location network_id_where;   // the `network_id` value, when written
  Location interface_where;    // the `interface` value, when written
};

// OMG DDS Security 1.1 for the gateway's participant (publish.dds.security;
// docs/guides/secure-dds.md): the builtin plugins of Cyclone DDS, configured with the domain. Every
// file is required; a relative path is taken from the mapping file's folder
// (docs/reference/mapping-file.md#paths).
struct DdsSecurityConfig {
  enum File : std::size_t { IdentityCa, Certificate, PrivateKey, PermissionsCa, Governance, Permissions, kFiles };
  // The keys in the mapping file, and the settings' names in messages (publish.dds.security.<key>).
  static constexpr std::array<std::string_view, kFiles> kKeys = {"identity_ca",    "certificate", "private_key",
                                                                 "permissions_ca", "governance",  "permissions"};
  std::array<std::string, kFiles> path;  // as resolved
  std::array<Location, kFiles> where;    // each value
  Location section;                      // the `security` key
};

struct DdsConfig {
  bool enabled = false;
  std::uint32_t domain = 0;
  std::string partition = "oegw";
  // "loopback" (nothing leaves the host: tests, demo), an interface name (the cab network), or
  // "" (Cyclone's own configuration, CYCLONEDDS_URI).
  std::string network = "loopback";
  std::optional<DdsSecurityConfig> security;  // absent: no DDS Security
  Location where;                             // the `dds` section, when written
  Location network_where;                     // the `network` value, when written
};
struct LcmConfig {
  bool enabled = false;
  // Host-local by default: ttl=0 keeps the data on the host, and the all-hosts group 224.0.0.1
  // is the one group the kernel never reports by IGMP (RFC 2236 §6, RFC 3376 §5), so not even
  // a membership report leaves. A deployment names its group, e.g. udpm://239.255.76.67:7667?ttl=1.
  std::string url = "udpm://224.0.0.1:7667?ttl=0";
  std::string channel_prefix = "OEGW_";
  Location where;      // the `lcm` section, when written
  Location url_where;  // the `url` value, when written
};
struct PublishConfig {
  std::uint32_t period_ms = 100;  // every FE is published on change and at least this often
  DdsConfig dds;
  LcmConfig lcm;
};

// The local control socket `oegw run` serves (`oegw status`, later `oegw ctl`; the protocol:
// docs/reference/control-protocol.md). A Unix stream socket only: nothing listens on a network.
inline constexpr std::string_view kDefaultControlSocket = "/run/oegw/oegw.sock";
struct ControlConfig {
  bool enabled = true;
  std::string socket{kDefaultControlSocket};  // an absolute path, shorter than sun_path
  // The group that may ask besides root (socket mode 0660, group = this); empty: the socket is
  // its owner's only (mode 0600). `oegw run` refuses a group this machine does not have.
  std::string group;
  Location where;         // the section, when written
  Location socket_where;  // the `socket` value, when written
  Location group_where;   // the `group` value, when written
};
// The longest socket path a sockaddr_un takes (108 bytes with its NUL, Linux unix(7)).
inline constexpr std::size_t kMaxControlSocketPath = 107;

// The black box (docs/guides/black-box.md): `oegw run` records both buses' frames and its
// decisions into a ring of segment files in `dir`, at most `max_mib` MiB and `span_s` seconds,
// closed in `segments` parts (a segment at max/segments bytes or span/segments seconds), through
// an in-memory queue of `queue_kib` KiB (what does not fit is dropped and counted). Off unless
// `enabled`.
struct RecordConfig {
  bool enabled = false;
  std::string dir = "/var/lib/oegw/record";  // a relative path is taken from the file's folder
  std::uint32_t max_mib = 256;
  std::uint32_t span_s = 600;
  std::uint32_t segments = 10;
  std::uint32_t queue_kib = 4096;
  Location where;      // the section, when written
  Location dir_where;  // the `dir` value, when written
};

struct SdoWriteConfig {
  std::uint16_t index = 0;
  std::uint8_t sub_index = 0;
  std::int64_t value = 0;
  canopen::DataType type = canopen::DataType::Unsigned32;
  Location where;
  [[nodiscard]] subdevices::SdoWrite to_sdo_write() const;  // little-endian bytes of `type`
};

// A sub-device's name: a-z, 0-9 and _ (it names DDS/LCM fields and log lines).
[[nodiscard]] bool valid_subdevice_name(std::string_view name);
// CANopen node-IDs 1..127: no more sub-devices than that on one bus.
inline constexpr std::size_t kMaxSubdevices = 127;

struct SubdeviceConfig {
  std::string name;    // "right_grip"
  std::string driver;  // "elobau-mfg", "mcb402", "novotechnik-406", "cia401"
  std::uint8_t node_id = 0;
  std::uint16_t heartbeat_ms = 100;
  std::uint16_t heartbeat_timeout_ms = 0;  // 0 = 1.5 x heartbeat_ms
  std::uint16_t pdo_timeout_ms = 0;        // PDO freshness deadline; 0 = 3 x the event timers (driver.hpp)
  bool mandatory = false;
  subdevices::ExpectedIdentity identity;
  // identity.revision_match: `major` (default) compares the upper 16 bits of 1018h:03 only,
  // `exact` all 32 (NodeSettings::exact_revision).
  bool exact_revision = false;
  std::vector<SdoWriteConfig> sdo;
  subdevices::DriverOptions options;
  std::vector<std::pair<std::string, Location>> option_where;  // each option's value, as written
  std::vector<subdevices::SignalInfo> signals;                 // from the catalogue
  Location where;
  [[nodiscard]] subdevices::NodeId node() const { return subdevices::NodeId{node_id}; }
  [[nodiscard]] const subdevices::SignalInfo* find_signal(std::string_view name) const;
  // What the downstream network manager needs for this node (the sdo list as byte writes).
  [[nodiscard]] subdevices::NodeSettings node_settings() const;
};

// One FE field and the signal feeding it (input FEs) or fed by it (indicators, displays).
struct FieldBinding {
  FeField field;                   // name, index, sub-index, bit, type
  std::string subdevice;           // "right_grip"
  std::string signal;              // "x", "buttons[3]"
  std::uint8_t signal_bit = 0xFF;  // one bit of a bit-packed signal (CiA 401 byte) feeds/drives this
                                   // one-bit field; 0xFF = the whole value (translate.hpp)
  subdevices::SignalInfo signal_info;
  FieldOptions options;  // as written
  Location where;        // the field's key
  [[nodiscard]] InputParams input_params() const { return resolve_input(signal_info, field, options, signal_bit); }
  [[nodiscard]] OutputParams output_params() const { return resolve_output(signal_info, field, options, signal_bit); }
};

// Who may command an output FE (indicators, display). CiA 852 has the host write 6200h/6411h
// over CANopen; the gateway adds the machine application over DDS and LCM. An FE lists the
// sources it takes (`sources: [canopen, dds, lcm]` in the mapping file; canopen and dds when
// absent); among them the last write wins. LCM only when listed: liblcm neither authenticates
// nor names a message's sender, so whoever reaches the LCM port could light the cab's lamps
// (docs/design/threat-model.md); a mapping file opts in, and `oegw check` warns when that URL
// reaches beyond this host (mapping/deployment.hpp). A write from a source not listed changes
// nothing: over CANopen an SDO download is aborted with 0800 0021h (CiA 301 Table 22, "local
// control") and the FE's bytes in an RPDO are ignored; over DDS/LCM the command is dropped and
// logged.
enum class CommandSource : std::uint8_t { Canopen = 1, Dds = 2, Lcm = 4 };
using CommandSources = std::uint8_t;  // a set of CommandSource bits
inline constexpr CommandSources kAllCommandSources = 7;
inline constexpr CommandSources kDefaultCommandSources = 3;          // canopen, dds: LCM is opt-in
[[nodiscard]] std::string_view to_string(CommandSource s);           // "canopen", "dds", "lcm"
[[nodiscard]] std::string describe_sources(CommandSources sources);  // "canopen, dds"

struct FunctionalElementConfig {
  FeId id;
  std::vector<FieldBinding> fields;                 // in the FE's dictionary order
  CommandSources sources = kDefaultCommandSources;  // output FEs only
  // Output FEs: when no accepted command (from any listed source) arrives for this long, the
  // FE's outputs take their CiA 401 error values (6206h/6207h, 6443h/6444h) until the next
  // command. 0 = no watchdog (a commander may send on change only).
  std::uint32_t command_timeout_ms = 0;
  Location where;
  Location sources_where;  // the `sources` value, when written
  [[nodiscard]] bool input() const { return is_input(id.kind); }
  [[nodiscard]] bool accepts(CommandSource s) const { return (sources & static_cast<CommandSources>(s)) != 0; }
};

struct Config {
  std::string file;
  UpstreamConfig upstream;
  DownstreamConfig downstream;
  PublishConfig publish;
  ControlConfig control;
  RecordConfig record;
  std::vector<SubdeviceConfig> subdevices;                   // in file order
  std::vector<FunctionalElementConfig> functional_elements;  // sorted by FeId
  [[nodiscard]] const SubdeviceConfig* find_subdevice(std::string_view name) const;
  [[nodiscard]] const FunctionalElementConfig* find_fe(FeId id) const;
};

struct LoadResult {
  std::optional<Config> config;    // set iff errors is empty
  std::vector<Diagnostic> errors;  // in file order
  [[nodiscard]] bool ok() const { return config.has_value(); }
  [[nodiscard]] std::string error_text() const;  // one diagnostic per line
};

// Reads and validates the mapping file at `path`. A relative path in it (an `eds:` option, the
// upstream store) is taken from the folder `path` is in, not from the working directory.
[[nodiscard]] LoadResult load_config(const std::string& path, const SignalCatalogue& catalogue);
// The same for text already in memory; `file` names it in the diagnostics; a relative path in it
// is taken from `base`, or left as written without one.
[[nodiscard]] LoadResult load_config_text(std::string_view text, std::string_view file,
                                          const SignalCatalogue& catalogue,
                                          std::optional<std::filesystem::path> base = std::nullopt);

}  // namespace oegw::mapping
