// CiA 309-3 command lines (canopen/309/ascii_gateway.hpp): every data type both ways, the
// command forms of lely's coctl documentation and CANopenNode's CO_gateway_ascii.h, and the
// exact error answers for bad lines.
#include "canopen/309/ascii_gateway.hpp"

#include <gtest/gtest.h>

namespace oegw::canopen::ascii {
namespace {

using Bytes = std::vector<std::uint8_t>;

Request ok(std::string_view line, const Defaults& d = {}) {
  const Parsed p = parse(line, d);
  EXPECT_EQ(p.kind, Parsed::Kind::Ok) << line << ": " << p.message;
  return p.request;
}
// The answer line a bad command gets (its sequence, or 0).
std::string refused(std::string_view line, const Defaults& d = {}) {
  const Parsed p = parse(line, d);
  EXPECT_EQ(p.kind, Parsed::Kind::Error) << line;
  return answer_error(p.request.sequence.value_or(0), p.error, p.message);
}
Bytes written(std::string_view type_and_value) { return ok("[1] 1 5 w 0x2000 1 " + std::string(type_and_value)).data; }

TEST(AsciiGateway, ReadAsCoctlDocumentsIt) {
  // lely coctl.md's session: "[5] r 0x1018 0x01 u32" after `set network 1`, `set node 2`
  // (with the index and sub-index as two tokens, CiA 309-3 / CANopenNode).
  const Request r = ok("[5] r 0x1018 0x01 u32", Defaults{1, 2});
  EXPECT_EQ(r.sequence, 5u);
  EXPECT_EQ(r.command, Command::Read);
  EXPECT_EQ(r.network, 1);
  EXPECT_EQ(r.node, 2);
  EXPECT_EQ(r.index, 0x1018);
  EXPECT_EQ(r.sub, 1);
  EXPECT_EQ(r.type, DataType::U32);
  // CANopenNode's example: "[1] 4 read 0x1017 0 i16" (node 4 on the default network).
  const Request c = ok("[1] 4 read 0x1017 0 i16", Defaults{2, {}});
  EXPECT_EQ(c.network, 2);
  EXPECT_EQ(c.node, 4);
  EXPECT_EQ(c.index, 0x1017);
  EXPECT_EQ(c.type, DataType::I16);
  // Net and node given, commands case-insensitive, decimal and octal numbers as ISO C.
  const Request n = ok("[7] 2 11 READ 4120 010 U8");
  EXPECT_EQ(n.network, 2);
  EXPECT_EQ(n.node, 11);
  EXPECT_EQ(n.index, 4120);
  EXPECT_EQ(n.sub, 8);
  // The sequence may be left out; a trailing comment is ignored.
  const Request s = ok("2 11 r 0x1000 0 u32   # device type");
  EXPECT_FALSE(s.sequence.has_value());
}

TEST(AsciiGateway, EveryTypeWritten) {
  EXPECT_EQ(written("b 1"), (Bytes{1}));
  EXPECT_EQ(written("u8 255"), (Bytes{0xFF}));
  EXPECT_EQ(written("u16 0x1234"), (Bytes{0x34, 0x12}));
  EXPECT_EQ(written("u32 0xDEADBEEF"), (Bytes{0xEF, 0xBE, 0xAD, 0xDE}));
  EXPECT_EQ(written("u64 0x0102030405060708"), (Bytes{8, 7, 6, 5, 4, 3, 2, 1}));
  EXPECT_EQ(written("i8 -128"), (Bytes{0x80}));
  EXPECT_EQ(written("i16 -2"), (Bytes{0xFE, 0xFF}));
  EXPECT_EQ(written("i32 -1"), (Bytes{0xFF, 0xFF, 0xFF, 0xFF}));
  EXPECT_EQ(written("i64 -9223372036854775808"), (Bytes{0, 0, 0, 0, 0, 0, 0, 0x80}));
  EXPECT_EQ(written("r32 1.5"), (Bytes{0x00, 0x00, 0xC0, 0x3F}));
  EXPECT_EQ(written("r64 -2"), (Bytes{0, 0, 0, 0, 0, 0, 0, 0xC0}));
  EXPECT_EQ(written("vs \"Hello, \"\"World\"\"!\""),
            (Bytes{'H', 'e', 'l', 'l', 'o', ',', ' ', '"', 'W', 'o', 'r', 'l', 'd', '"', '!'}));
  EXPECT_EQ(written("vs two words"), (Bytes{'t', 'w', 'o', ' ', 'w', 'o', 'r', 'd', 's'}));
  EXPECT_EQ(written("os AQID"), (Bytes{1, 2, 3}));
  EXPECT_EQ(written("d AAE="), (Bytes{0, 1}));
}

TEST(AsciiGateway, EveryTypeRead) {
  EXPECT_EQ(format(DataType::B, Bytes{1}), "1");
  // lely's example answer for 1018h:01 u32: "[5] 0x00000360".
  EXPECT_EQ(format(DataType::U32, Bytes{0x60, 0x03, 0, 0}), "0x00000360");
  EXPECT_EQ(format(DataType::U8, Bytes{5}), "0x05");
  EXPECT_EQ(format(DataType::U16, Bytes{0x34, 0x12}), "0x1234");
  EXPECT_EQ(format(DataType::U64, Bytes{8, 7, 6, 5, 4, 3, 2, 1}), "0x0102030405060708");
  EXPECT_EQ(format(DataType::I8, Bytes{0x80}), "-128");
  EXPECT_EQ(format(DataType::I16, Bytes{0xFE, 0xFF}), "-2");
  EXPECT_EQ(format(DataType::I32, Bytes{0x01, 0, 0, 0}), "1");
  EXPECT_EQ(format(DataType::I64, Bytes{0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF}), "-1");
  EXPECT_EQ(format(DataType::R32, Bytes{0x00, 0x00, 0xC0, 0x3F}), "1.5");
  EXPECT_EQ(format(DataType::R64, Bytes{0, 0, 0, 0, 0, 0, 0, 0xC0}), "-2");
  EXPECT_EQ(format(DataType::VS, Bytes{'a', '"', 'b'}), "\"a\"\"b\"");
  EXPECT_EQ(format(DataType::OS, Bytes{1, 2, 3}), "AQID");
  EXPECT_EQ(format(DataType::D, Bytes{0, 1}), "AAE=");
  // A value whose length does not fit the type: no text (the caller answers 0607 0010h).
  EXPECT_EQ(format(DataType::U16, Bytes{1}), std::nullopt);
  EXPECT_EQ(format(DataType::U32, Bytes{1, 2, 3, 4, 5}), std::nullopt);
}

TEST(AsciiGateway, RoundTripsThroughBase64) {
  for (std::size_t n = 0; n < 8; ++n) {
    Bytes b;
    for (std::size_t i = 0; i < n; ++i) b.push_back(static_cast<std::uint8_t>(0xF0 + i * 7));
    EXPECT_EQ(base64_decode(base64_encode(b)), b) << n;
  }
  EXPECT_EQ(base64_decode("AQI"), std::nullopt);   // not a multiple of 4
  EXPECT_EQ(base64_decode("A=QI"), std::nullopt);  // padding inside
  EXPECT_EQ(base64_decode("AQ*D"), std::nullopt);
}

TEST(AsciiGateway, OtherCommands) {
  const Defaults d{2, 11};
  EXPECT_EQ(ok("[1] start", d).command, Command::Start);
  EXPECT_EQ(ok("[2] 12 stop", d).node, 12);
  EXPECT_EQ(ok("[3] preop", d).command, Command::PreOperational);
  EXPECT_EQ(ok("[4] preoperational", d).command, Command::PreOperational);
  EXPECT_EQ(ok("[5] 2 11 reset node").command, Command::ResetNode);
  EXPECT_EQ(ok("[6] reset comm", d).command, Command::ResetCommunication);
  EXPECT_EQ(ok("[7] reset communication", d).command, Command::ResetCommunication);
  const Request net = ok("[8] set network 2");
  EXPECT_EQ(net.command, Command::SetNetwork);
  EXPECT_EQ(net.value, 2u);
  const Request node = ok("[9] 2 set node 11");
  EXPECT_EQ(node.command, Command::SetNode);
  EXPECT_EQ(node.network, 2);
  EXPECT_EQ(node.value, 11u);
  const Request to = ok("[10] set sdo_timeout 250", d);
  EXPECT_EQ(to.command, Command::SetSdoTimeout);
  EXPECT_EQ(to.network, 2);
  EXPECT_EQ(to.value, 250u);
  EXPECT_EQ(ok("[11] info version").command, Command::InfoVersion);
  EXPECT_EQ(parse("   # only a comment", {}).kind, Parsed::Kind::Empty);
  EXPECT_EQ(parse("", {}).kind, Parsed::Kind::Empty);
}

TEST(AsciiGateway, AnswersAndEvents) {
  EXPECT_EQ(answer_ok(3), "[3] OK");
  EXPECT_EQ(answer_value(5, "0x00000360"), "[5] 0x00000360");
  EXPECT_EQ(answer_abort(6, SdoAbortCode::CannotTransferLocalControl),
            "[6] ERROR: 08000021 (" + std::string(to_string(SdoAbortCode::CannotTransferLocalControl)) + ")");
  EXPECT_EQ(answer_error(7, GatewayError::NoDefaultNode), "[7] ERROR: 105 (No default node set)");
  EXPECT_EQ(boot_up_event(2, 11), "2 11 BOOT_UP");
  const std::array<std::uint8_t, 5> m{1, 2, 3, 4, 255};
  EXPECT_EQ(emcy_event(2, 11, 0x8130, 0x11, m), "2 11 EMCY 8130 11 1 2 3 4 255");
}

TEST(AsciiGateway, BadLinesGetExactErrors) {
  EXPECT_EQ(
      refused("[1] r 0x1018 1 u32"),
      "[1] ERROR: 104 (No default net set: give the network and node before the command or `set network N` first)");
  EXPECT_EQ(refused("[2] r 0x1018 1 u32", Defaults{2, {}}),
            "[2] ERROR: 105 (No default node set: give the node before the command or `set node N` first)");
  EXPECT_EQ(refused("[3] 2 200 r 0x1018 1 u32"), "[3] ERROR: 107 (Unsupported node: node 200 (1..127))");
  EXPECT_EQ(refused("[4] 300 5 r 0x1018 1 u32"), "[4] ERROR: 106 (Unsupported net: network 300 (1..127))");
  EXPECT_EQ(refused("[5] 2 5 r 0x1018 1 u9"),
            "[5] ERROR: 101 (Syntax error: 'u9' is no data type; one of b, u8, u16, u32, u64, i8, i16, i32, i64, r32, "
            "r64, vs, os, d)");
  EXPECT_EQ(refused("[6] 2 5 r 0x10000 1 u8"),
            "[6] ERROR: 101 (Syntax error: index 0x10000 is out of range (0..65535))");
  EXPECT_EQ(refused("[7] 2 5 r 0x1018 256 u8"),
            "[7] ERROR: 101 (Syntax error: sub-index 256 is out of range (0..255))");
  EXPECT_EQ(refused("[8] 2 5 r 0x1018 1"),
            "[8] ERROR: 101 (Syntax error: expected r[ead] <index> <sub-index> <data type>)");
  EXPECT_EQ(refused("[9] 2 5 w 0x2000 1 u8 256"), "[9] ERROR: 101 (Syntax error: 256 is out of range for u8 (0..255))");
  EXPECT_EQ(refused("[10] 2 5 w 0x2000 1 i8 -129"),
            "[10] ERROR: 101 (Syntax error: -129 is out of range for i8 (-128..127))");
  EXPECT_EQ(refused("[11] 2 5 w 0x2000 1 u16 -1"),
            "[11] ERROR: 101 (Syntax error: -1 is out of range for u16 (0..65535))");
  EXPECT_EQ(refused("[12] 2 5 w 0x2000 1 u32 12abc"),
            "[12] ERROR: 101 (Syntax error: '12abc' is no u32 value (a number such as 5, -5 or 0x1F))");
  EXPECT_EQ(refused("[13] 2 5 w 0x2000 1 r32 fast"),
            "[13] ERROR: 101 (Syntax error: 'fast' is no r32 value (a number such as 1.5 or -2e3))");
  EXPECT_EQ(refused("[14] 2 5 w 0x2000 1 r32 1e39"), "[14] ERROR: 101 (Syntax error: 1e39 is out of range for r32)");
  EXPECT_EQ(refused("[15] 2 5 w 0x2000 1 os AQ*D"),
            "[15] ERROR: 101 (Syntax error: 'AQ*D' is no MIME Base64 text (RFC 2045), as os values are written)");
  EXPECT_EQ(refused("[16] 2 5 w 0x2000 1 vs \"open"),
            "[16] ERROR: 101 (Syntax error: a string opened with \" is not closed)");
  EXPECT_EQ(refused("[28] 2 5 w 0x2000 1 vs \"a\" b"),
            "[28] ERROR: 101 (Syntax error: text after the quoted vs value)");
  EXPECT_EQ(refused("[29] 2 5 w 0x2000 1 vs a \"b\""),
            "[29] ERROR: 101 (Syntax error: a vs value is one quoted string or unquoted words)");
  EXPECT_EQ(refused("[17] 2 5 w 0x2000 1 u8 1 2"),
            "[17] ERROR: 101 (Syntax error: a u8 value is one token; text follows '1')");
  EXPECT_EQ(
      refused("[18] 2 5 fly"),
      "[18] ERROR: 100 (Request not supported: no command 'fly'; this gateway has r[ead], w[rite], start, stop, "
      "preop[erational], reset node, reset comm[unication], set network, set node, set sdo_timeout, info version, "
      "lss_switch_glob, lss_switch_sel, lss_set_node, lss_conf_bitrate, lss_activate_bitrate, lss_store, "
      "lss_inquire_addr, lss_get_node, lss_identity, lss_ident_nonconf, _lss_fastscan, _lss_slowscan)");
  EXPECT_EQ(refused("[19] 2 0 start"), "[19] ERROR: 100 (Request not supported: node 0 (all nodes): name each node)");
  EXPECT_EQ(refused("[20] set network 0"), "[20] ERROR: 101 (Syntax error: network 0 is out of range (1..127))");
  EXPECT_EQ(refused("[21] set sdo_timeout 0", Defaults{2, {}}),
            "[21] ERROR: 101 (Syntax error: SDO time-out in ms 0 is out of range (1..65535))");
  EXPECT_EQ(refused("[22] set heartbeat 100"),
            "[22] ERROR: 100 (Request not supported: `set heartbeat`; this gateway has set network, set node, set "
            "sdo_timeout)");
  EXPECT_EQ(refused("[23] reset"), "[23] ERROR: 101 (Syntax error: expected `reset node` or `reset comm[unication]`)");
  EXPECT_EQ(refused("[x] info version"),
            "[0] ERROR: 101 (Syntax error: 'x' is no sequence number (a number such as 5 or 0x1018))");
  EXPECT_EQ(refused("[24"), "[0] ERROR: 101 (Syntax error: '[' opens a sequence number but no ']' closes it)");
  EXPECT_EQ(refused("[25]"), "[25] ERROR: 101 (Syntax error: a sequence number and no command)");
  EXPECT_EQ(refused("[26] 1 2 3 r 0x1000 0 u32"),
            "[26] ERROR: 101 (Syntax error: more than two numbers (network and node) before the command)");
  EXPECT_EQ(refused("[27] 2 info version"),
            "[27] ERROR: 101 (Syntax error: `info version` takes no network or node before it)");
}

// The LSS commands as CANopenNode's CO_gateway_ascii.c help text and lely's coctl.md spell them
// ("All LSS commands start with '[<sequence>] [<net>]'"), and lely's test session (lss_ident_nonconf,
// lss_switch_sel 0x360 0 0 0, lss_get_node, lss_set_node 2, lss_conf_bitrate 0 ..., lss_store).
TEST(AsciiGateway, LssCommands) {
  const Defaults d{2, {}};
  const Request glob = ok("[1] lss_switch_glob 1", d);
  EXPECT_EQ(glob.command, Command::LssSwitchGlobal);
  EXPECT_EQ(glob.network, 2);
  EXPECT_EQ(glob.value, 1u);
  EXPECT_EQ(ok("[2] 2 lss_switch_glob 0").value, 0u);
  const Request sel = ok("[3] lss_switch_sel 0x360 0 0 0", d);
  EXPECT_EQ(sel.command, Command::LssSwitchSelective);
  EXPECT_EQ(sel.address, (std::array<std::uint32_t, 4>{0x360, 0, 0, 0}));
  EXPECT_EQ(ok("[4] 2 lss_switch_sel 0xA5A 0x402 0x00010002 4294967295").address,
            (std::array<std::uint32_t, 4>{0xA5A, 0x402, 0x10002, 0xFFFFFFFF}));
  const Request set = ok("[5] lss_set_node 2", d);
  EXPECT_EQ(set.command, Command::LssSetNode);
  EXPECT_EQ(set.value, 2u);
  EXPECT_EQ(ok("[6] lss_set_node 255", d).value, 255u);  // none (CiA 305: FFh, unconfigured)
  const Request rate = ok("[7] lss_conf_bitrate 0 3", d);
  EXPECT_EQ(rate.command, Command::LssConfBitrate);
  EXPECT_EQ(rate.value, 3u);  // 250 kbit/s
  const Request act = ok("[8] lss_activate_bitrate 100", d);
  EXPECT_EQ(act.command, Command::LssActivateBitrate);
  EXPECT_EQ(act.value, 100u);
  EXPECT_EQ(ok("[9] lss_store", d).command, Command::LssStore);
  const Request all = ok("[10] lss_inquire_addr", d);
  EXPECT_EQ(all.command, Command::LssInquireAddress);
  EXPECT_EQ(all.lss_part, std::nullopt);
  EXPECT_EQ(ok("[11] lss_inquire_addr 3", d).lss_part, 3);     // CANopenNode: LSSSUB 0..3
  EXPECT_EQ(ok("[12] lss_inquire_addr 0x5B", d).lss_part, 1);  // lely: the command specifier
  EXPECT_EQ(ok("[13] lss_get_node", d).command, Command::LssGetNode);
  EXPECT_EQ(ok("[14] lss_ident_nonconf", d).command, Command::LssIdentNonConfigured);
  const Request fs = ok("[15] _lss_fastscan", d);
  EXPECT_EQ(fs.command, Command::LssFastscan);
  EXPECT_EQ(fs.value, 0u);  // the gateway's step time-out
  EXPECT_EQ(ok("[16] 2 _lss_fastscan 200").value, 200u);
  EXPECT_EQ(ok("[17] LSS_STORE", d).command, Command::LssStore);  // commands are case-insensitive
  // lely-core's gateway test session (its [11], [13], [15]): slowscan, fastscan with known bits,
  // identify remote slave.
  const Request slow = ok("[11] _lss_slowscan 0x360 0 0 0 0 0", d);
  EXPECT_EQ(slow.command, Command::LssSlowscan);
  EXPECT_EQ(slow.range, (std::array<std::uint32_t, 6>{0x360, 0, 0, 0, 0, 0}));
  const Request known = ok("[13] _lss_fastscan 0 0xffff0000 0 0xffffffff 0 0xffffffff 0 0xffffffff", d);
  EXPECT_EQ(known.command, Command::LssFastscan);
  EXPECT_EQ(known.address, (std::array<std::uint32_t, 4>{0, 0, 0, 0}));
  EXPECT_EQ(known.known_mask, (std::array<std::uint32_t, 4>{0xFFFF0000, 0xFFFFFFFF, 0xFFFFFFFF, 0xFFFFFFFF}));
  EXPECT_EQ(fs.known_mask, std::nullopt);
  const Request ident = ok("[15] lss_identity 0x360 0 0 0 0 0", d);
  EXPECT_EQ(ident.command, Command::LssIdentity);
  EXPECT_EQ(ok("[18] 2 lss_identity 0xA5A 0x402 0 0xFFFFFFFF 0 4294967295").range,
            (std::array<std::uint32_t, 6>{0xA5A, 0x402, 0, 0xFFFFFFFF, 0, 0xFFFFFFFF}));
  for (const auto c : {Command::LssIdentity, Command::LssSlowscan}) EXPECT_TRUE(is_lss(c));
  for (const auto c : {Command::LssSwitchGlobal, Command::LssFastscan, Command::LssStore}) EXPECT_TRUE(is_lss(c));
  for (const auto c : {Command::Read, Command::Start, Command::InfoVersion}) EXPECT_FALSE(is_lss(c));
}

TEST(AsciiGateway, LssCommandsWithBadArguments) {
  const Defaults d{2, {}};
  EXPECT_EQ(refused("[1] lss_store"),
            "[1] ERROR: 104 (No default net set: give the network before the command or `set network N` first)");
  EXPECT_EQ(refused("[2] 2 17 lss_store"),
            "[2] ERROR: 101 (Syntax error: 'lss_store' takes a network number only, not a node)");
  EXPECT_EQ(refused("[3] 200 lss_store"), "[3] ERROR: 106 (Unsupported net: network 200 (1..127))");
  EXPECT_EQ(refused("[4] lss_switch_glob 2", d),
            "[4] ERROR: 101 (Syntax error: expected lss_switch_glob 0|1 (0 waiting, 1 configuration))");
  EXPECT_EQ(refused("[5] lss_switch_glob", d),
            "[5] ERROR: 101 (Syntax error: expected lss_switch_glob 0|1 (0 waiting, 1 configuration))");
  EXPECT_EQ(refused("[6] lss_switch_sel 1 2 3", d),
            "[6] ERROR: 101 (Syntax error: expected lss_switch_sel <vendor-ID> <product code> <revision> <serial>)");
  EXPECT_EQ(refused("[7] lss_switch_sel 1 2 3 0x100000000", d),
            "[7] ERROR: 101 (Syntax error: '0x100000000' is no 32-bit number; expected lss_switch_sel <vendor-ID> "
            "<product code> <revision> <serial>)");
  EXPECT_EQ(refused("[8] lss_set_node 0", d), "[8] ERROR: 101 (Syntax error: node-ID '0': 1..127, or 255 (none))");
  EXPECT_EQ(refused("[9] lss_set_node 128", d), "[9] ERROR: 101 (Syntax error: node-ID '128': 1..127, or 255 (none))");
  EXPECT_EQ(refused("[10] lss_set_node", d),
            "[10] ERROR: 101 (Syntax error: expected lss_set_node <node-ID 1..127, or 255: none>)");
  EXPECT_EQ(refused("[11] lss_conf_bitrate 3", d),
            "[11] ERROR: 101 (Syntax error: expected lss_conf_bitrate 0 <table index: 0 1000, 1 800, 2 500, 3 250, 4 "
            "125, 6 50, 7 20, 8 10 kbit/s>)");
  EXPECT_EQ(refused("[12] lss_conf_bitrate 1 3", d),
            "[12] ERROR: 503 (LSS bit-rate not supported: table selector 1: only 0, the CiA 305 standard table)");
  EXPECT_EQ(refused("[13] lss_conf_bitrate 0 5", d),
            "[13] ERROR: 503 (LSS bit-rate not supported: table index 5 is not in the CiA 305 table (0 1000, 1 800, 2 "
            "500, 3 250, 4 125, 6 50, 7 20, 8 10 kbit/s))");
  EXPECT_EQ(refused("[14] lss_activate_bitrate 65536", d),
            "[14] ERROR: 101 (Syntax error: expected lss_activate_bitrate <switch delay in ms, 0..65535>)");
  EXPECT_EQ(refused("[15] lss_store now", d), "[15] ERROR: 101 (Syntax error: expected lss_store)");
  EXPECT_EQ(refused("[16] lss_inquire_addr 4", d),
            "[16] ERROR: 101 (Syntax error: expected lss_inquire_addr [<part: 0..3 or 0x5A..0x5D (vendor, product, "
            "revision, serial)>])");
  EXPECT_EQ(refused("[17] lss_get_node 1", d), "[17] ERROR: 101 (Syntax error: expected lss_get_node)");
  const std::string fastscan_usage =
      "expected _lss_fastscan [<step time-out in ms, 1..65535>], or lely's _lss_fastscan <vendor-ID> <mask> <product "
      "code> <mask> <revision> <mask> <serial> <mask> (a mask's 1 bits are known))";
  EXPECT_EQ(refused("[18] _lss_fastscan 0", d), "[18] ERROR: 101 (Syntax error: " + fastscan_usage);
  EXPECT_EQ(refused("[19] _lss_fastscan 0 0xffff0000 0 0xffffffff 0 0xffffffff 0", d),
            "[19] ERROR: 101 (Syntax error: " + fastscan_usage);
  EXPECT_EQ(refused("[20] lss_allnodes", d),
            "[20] ERROR: 100 (Request not supported: no command 'lss_allnodes'; this gateway's LSS commands are "
            "lss_switch_glob, lss_switch_sel, lss_set_node, lss_conf_bitrate, lss_activate_bitrate, lss_store, "
            "lss_inquire_addr, lss_get_node, lss_identity, lss_ident_nonconf, _lss_fastscan, _lss_slowscan)");
  EXPECT_EQ(refused("[23] lss_identity 0x360 0 0 0 0", d),
            "[23] ERROR: 101 (Syntax error: expected lss_identity <vendor-ID> <product code> <revision low> <revision "
            "high> <serial low> <serial high>)");
  EXPECT_EQ(
      refused("[24] _lss_slowscan 0x360 0 5 4 0 0", d),
      "[24] ERROR: 101 (Syntax error: a range's low end above its high end (revision low..high, serial low..high))");
  EXPECT_EQ(refused("[25] _lss_fastscan 0 0 0 0 0 0 0 0x1FFFFFFFF", d),
            "[25] ERROR: 101 (Syntax error: '0x1FFFFFFFF' is no 32-bit number; " + fastscan_usage);
  EXPECT_EQ(answer_error(21, GatewayError::LssNodeIdNotSupported, "configure node-ID refused with LSS error code 1"),
            "[21] ERROR: 502 (LSS node-ID not supported: configure node-ID refused with LSS error code 1)");
  EXPECT_EQ(answer_error(22, GatewayError::LssMediaError),
            "[22] ERROR: 505 (LSS command failed because of media error)");
}

}  // namespace
}  // namespace oegw::canopen::ascii
