// What an LCM URL (publish.lcm.url) reaches, read the way liblcm reads it: the one rule the
// mapping file applies to it, and whether this machine can route its group. Standard library and
// libc only, so that the mapping file's checks and `oegw check` need no liblcm.
//
// The groups 224.0.0.0/24 reach every host of the link (RFC 5771 §4, "Local Network Control
// Block"). The gateway's host-local default udpm://224.0.0.1:7667?ttl=0 uses 224.0.0.1 because
// the kernel never sends an IGMP report for it (RFC 2236 §6, RFC 3376 §5), so nothing at all
// leaves the host; but with a ttl above 0 every device on the cab network would receive each
// sample. A network deployment uses an administratively scoped group (239.x.x.x, RFC 2365).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace oegw::publish {

// A udpm:// URL that sends to a link-local group with a ttl other than 0.
struct LinkLocalSend {
  std::string group;  // dotted quad, "224.0.0.1"
  std::string ttl;    // as written, "1"
};

// The URL's link-local send, or nullopt when the URL is not udpm://, its group is not in
// 224.0.0.0/24, or every ttl option reads exactly "0" (the last one counts, as for liblcm;
// absent means 0).
[[nodiscard]] std::optional<LinkLocalSend> link_local_send(std::string_view url);

// Why LCM messages from beyond this host reach a subscriber of `url`, or nullopt when only this
// host can send to it. liblcm 1.3.1's providers: udpm:// reaches beyond with a ttl other than 0
// (the gateway's own samples leave, and it is a network's group), or with any group but the
// all-hosts 224.0.0.1 (the kernel joins it on the interface the routing table picks and
// announces that by IGMP, RFC 3376 §5, inviting senders of the network); tcpq:// to a host other
// than the loopback (127.0.0.0/8, localhost); memq:// (in the process) and file:// (a log) do
// not. Anything else is not known to stay here. What it does not cover: 224.0.0.1:7667 is
// received on every interface, ttl=0 or not (a firewall closes that;
// docs/design/threat-model.md).
[[nodiscard]] std::optional<std::string> lcm_reaches_beyond_host(std::string_view url);

// An IPv4 address in the forms inet_aton(3) accepts (liblcm parses the group with it): "a.b.c.d",
// "a.b.c" (c 16 bits), "a.b" (b 24 bits), "a" (32 bits), each part decimal, 0-octal or 0x-hex,
// the text ending at a NUL or an ASCII white space. Host byte order.
[[nodiscard]] std::optional<std::uint32_t> parse_inet_aton(std::string_view text);

// The group of a udpm:// URL as liblcm reads it (239.255.76.67 when the URL names none), or
// nullopt for another provider or a group inet_aton(3) refuses.
[[nodiscard]] std::optional<std::uint32_t> udpm_group(std::string_view url);

// Why this machine cannot send to the udpm:// URL's group now, or nullopt when it can (or the URL
// is no udpm://): liblcm's own first test in lcm_create(), a UDP connect() to the group, which
// fails without a route for it (a controller whose only interface is lo: "Network is
// unreachable"); lcm_create() then gives up with a page on stderr. The text: "no route to
// 224.0.0.1 (Network is unreachable)".
[[nodiscard]] std::optional<std::string> lcm_route_problem(std::string_view url);

// The command that routes the udpm:// URL's multicast: `ip route add 224.0.0.0/4 dev lo` for a
// ttl=0 URL (its samples never leave the host), else `... dev DEVICE` (`device`, or
// "<the cab network's interface>" when empty).
[[nodiscard]] std::string lcm_route_command(std::string_view url, std::string_view device);

// "224.0.0.1" for 0xE0000001.
[[nodiscard]] std::string dotted_quad(std::uint32_t address);

}  // namespace oegw::publish
