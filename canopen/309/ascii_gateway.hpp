// CiA 309-3 ("Access from other networks — ASCII mapping"): the command lines `oegw ctl` takes
// and the answer and event lines it prints. Sans I/O: text in, requests and bytes out, and back.
//
// The CiA 309-3 text itself is not public; what this follows is what public sources print of it:
//  * lely-core's coctl documentation (doc/coctl.md) and its gateway (src/co/gw_txt.c): the
//    command forms, the data types and their syntax (b, u8..u64, i8..i64, r32, r64, vs, os, d),
//    a VISIBLE_STRING between double quotes with "" for a quote, OCTET_STRING and DOMAIN in MIME
//    Base64 (RFC 2045), numbers as ISO C writes them (0x.. hex, 0.. octal, decimal), the answers
//    "[seq] OK", "[seq] <value>", "[seq] ERROR: <abort code, 8 hex digits> (<text>)" and
//    "[seq] ERROR: <internal error code> (<text>)", the events "<net> <node> BOOT_UP" and
//    "<net> <node> EMCY <code, 4 hex> <register, 2 hex> <5 manufacturer bytes, decimal>", the
//    version answer "[seq] <vendor> <product> <rev hi>.<rev lo> <serial> <class> <prot hi>.<prot
//    lo> <impl hi>.<impl lo>", and an unsigned value printed as 0x with two digits per byte
//    (its example "[5] 0x00000360" for 1018h:01 u32).
//  * CANopenNode's CO_gateway_ascii.h ("CiA 309-3 DS v3.0.0"): the index and sub-index as two
//    tokens (`r[ead] <index> <subindex> <datatype>`, the form `oegw ctl` is required to take;
//    lely's multiplexer form is not taken), '#' comments, and the internal error codes (100 request
//    not supported, 101 syntax error, 102 internal state, 103 time-out, 104 no default net, 105 no
//    default node, 106 unsupported net, 107 unsupported node).
// Where the two differ (lely prints "ERROR: 06020000 (...)", CANopenNode "ERROR:0x06020000 #..."),
// lely's form is taken: `oegw ctl` is required to answer as coctl does.
//
// Choices of this project: the sequence "[n]" may be left out (the caller numbers the command
// then); r/w need a node 1..127, NMT commands a node 1..127 (0, "all nodes", is not supported:
// the gateway answers for the sub-devices it knows one by one); a syntax error's text says what
// was wrong ("ERROR: 101 (Syntax error: 'u9' is no data type; ...)").
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "canopen/types.hpp"

namespace oegw::canopen::ascii {

// CiA 309-3 internal error codes (as CANopenNode's CO_GTWA_respErrorCode_t lists them).
enum class GatewayError : int {
  None = 0,
  RequestNotSupported = 100,
  Syntax = 101,
  InternalState = 102,
  Timeout = 103,
  NoDefaultNet = 104,
  NoDefaultNode = 105,
  UnsupportedNet = 106,
  UnsupportedNode = 107,
  // LSS (CiA 305 answers with an error code; the same codes in lely's and CANopenNode's gateways).
  LssManufacturer = 501,         // error code FFh: implementation-specific
  LssNodeIdNotSupported = 502,   // configure node-ID answered error 1
  LssBitRateNotSupported = 503,  // configure bit timing answered error 1
  LssStoreFailed = 504,          // store configuration answered error 1 (not supported)
  LssMediaError = 505,           // store configuration answered error 2 (storage media)
};
[[nodiscard]] std::string_view to_string(GatewayError e);

enum class DataType : std::uint8_t { B, U8, U16, U32, U64, I8, I16, I32, I64, R32, R64, VS, OS, D };
// "u16" -> U16 (case-insensitive); nullopt for a name CiA 309-3 does not have (or this tool not).
[[nodiscard]] std::optional<DataType> parse_type(std::string_view name);
[[nodiscard]] std::string_view to_string(DataType t);
// Bytes of a fixed-size type; 0 for vs, os, d.
[[nodiscard]] std::size_t size_of(DataType t);
// "b, u8, u16, u32, u64, i8, i16, i32, i64, r32, r64, vs, os, d" (for the error texts, help).
[[nodiscard]] std::string type_names();

enum class Command : std::uint8_t {
  Read,
  Write,
  Start,
  Stop,
  PreOperational,
  ResetNode,
  ResetCommunication,
  SetNetwork,
  SetNode,
  SetSdoTimeout,
  InfoVersion,
  // CiA 309-3 LSS (CiA 305) commands, network-level: `[net] lss_...`.
  LssSwitchGlobal,        // lss_switch_glob 0|1                     (value: the mode)
  LssSwitchSelective,     // lss_switch_sel vendor product revision serial (address)
  LssSetNode,             // lss_set_node 1..127|255                  (value: the node-ID)
  LssConfBitrate,         // lss_conf_bitrate 0 index                 (value: the table index)
  LssActivateBitrate,     // lss_activate_bitrate delay_ms            (value: the delay)
  LssStore,               // lss_store
  LssInquireAddress,      // lss_inquire_addr [0..3 | 0x5A..0x5D]     (lss_part: the part, none: all four)
  LssGetNode,             // lss_get_node
  LssIdentNonConfigured,  // lss_ident_nonconf
  LssFastscan,            // _lss_fastscan [timeout_ms]              (value: the step time-out, 0: default)
                          // _lss_fastscan v vmask p pmask r rmask s smask (lely: address + known, mask)
  LssIdentity,            // lss_identity vendor product rev_lo rev_hi serial_lo serial_hi   (range)
  LssSlowscan,            // _lss_slowscan vendor product rev_lo rev_hi serial_lo serial_hi  (range, lely)
};
[[nodiscard]] bool is_lss(Command c);

struct Request {
  std::optional<std::uint32_t> sequence;  // "[n]"; nullopt when the line has none
  Command command = Command::Read;
  std::uint16_t network = 0;  // r/w/NMT/set node/set sdo_timeout: given or the default
  std::uint8_t node = 0;      // r/w/NMT: given or the default
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  DataType type = DataType::U8;
  std::vector<std::uint8_t> data;          // w: the value, little endian as CiA 301 sends it
  std::uint32_t value = 0;                 // set network / set node / set sdo_timeout / lss_* (see Command)
  std::array<std::uint32_t, 4> address{};  // lss_switch_sel: vendor, product, revision, serial;
                                           // _lss_fastscan's lely form: the known values
  std::optional<std::array<std::uint32_t, 4>> known_mask;  // _lss_fastscan's lely form: the masks
  // lss_identity, _lss_slowscan: vendor, product, revision low, high, serial low, high
  std::array<std::uint32_t, 6> range{};
  std::optional<std::uint8_t> lss_part;  // lss_inquire_addr: 0 vendor .. 3 serial; none: all four
};

// The defaults `set network` and `set node` gave (per session).
struct Defaults {
  std::optional<std::uint16_t> network;
  std::optional<std::uint8_t> node;
};

struct Parsed {
  enum class Kind : std::uint8_t { Empty, Ok, Error };  // Empty: blank line or only a comment
  Kind kind = Kind::Empty;
  Request request;  // Ok; for Error, request.sequence is the line's (when it could be read)
  GatewayError error = GatewayError::None;
  std::string message;  // Error: what was wrong, in words
};

[[nodiscard]] Parsed parse(std::string_view line, const Defaults& defaults);

// A value's text (after the data type of a write) as the bytes CiA 301 sends: nullopt and
// `error` set for a value the type does not take ("300 is out of range for u8 (0..255)").
[[nodiscard]] std::optional<std::vector<std::uint8_t>> encode(DataType t, std::string_view text, std::string& error);
// An uploaded value as CiA 309-3 prints it; nullopt when its length does not fit the type (the
// caller answers 0607 0010h, as lely's gateway does).
[[nodiscard]] std::optional<std::string> format(DataType t, std::span<const std::uint8_t> bytes);

// Answer lines (no newline).
[[nodiscard]] std::string answer_ok(std::uint32_t seq);
[[nodiscard]] std::string answer_value(std::uint32_t seq, const std::string& value);
[[nodiscard]] std::string answer_abort(std::uint32_t seq, SdoAbortCode code);
// "[seq] ERROR: 101 (Syntax error: <detail>)"; no detail: "(Syntax error)".
[[nodiscard]] std::string answer_error(std::uint32_t seq, GatewayError e, const std::string& detail = {});

// Event lines (no sequence).
[[nodiscard]] std::string boot_up_event(std::uint16_t network, std::uint8_t node);
[[nodiscard]] std::string emcy_event(std::uint16_t network, std::uint8_t node, std::uint16_t code,
                                     std::uint8_t error_register, std::span<const std::uint8_t, 5> msef);

// MIME Base64 (RFC 2045 §6.8) of os and d values. A hand-written codec of ~40 lines: the only
// Debian library offering one that the project links is OpenSSL's, through Cyclone DDS security,
// and the protocol core links no I/O or crypto library.
[[nodiscard]] std::string base64_encode(std::span<const std::uint8_t> bytes);
[[nodiscard]] std::optional<std::vector<std::uint8_t>> base64_decode(std::string_view text);

}  // namespace oegw::canopen::ascii
