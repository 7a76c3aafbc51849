#include "publish/lcm_url.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>

namespace oegw::publish {

namespace {

constexpr bool is_digit(char c) { return c >= '0' && c <= '9'; }
constexpr bool is_ascii_space(char c) {
  return c == ' ' || c == '\t' || c == '\n' || c == '\v' || c == '\f' || c == '\r';
}
constexpr int digit_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return 99;
}

// One part of an address as strtoul(..., 0) reads it: 0x-hex, 0-octal or decimal. `at` moves
// past the digits; nullopt beyond 32 bits.
std::optional<std::uint64_t> address_part(std::string_view s, std::size_t& at) {
  int base = 10;
  if (s[at] == '0') {
    base = 8;
    if (at + 2 < s.size() && (s[at + 1] == 'x' || s[at + 1] == 'X') && digit_value(s[at + 2]) < 16) {
      base = 16;
      at += 2;
    }
  }
  std::uint64_t v = 0;
  bool overflow = false;
  while (at < s.size() && digit_value(s[at]) < base) {
    v = v * static_cast<std::uint64_t>(base) + static_cast<std::uint64_t>(digit_value(s[at]));
    if (v > 0xFFFFFFFFu) {
      overflow = true;
      v = 0xFFFFFFFFu + 1u;
    }
    ++at;
  }
  if (overflow) return std::nullopt;
  return v;
}

}  // namespace

std::optional<std::uint32_t> parse_inet_aton(std::string_view text) {
  text = text.substr(0, text.find('\0'));
  static constexpr std::array<std::uint64_t, 4> kLastPartMax = {0xFFFFFFFFu, 0xFFFFFFu, 0xFFFFu, 0xFFu};
  std::array<std::uint32_t, 3> parts{};
  std::size_t n = 0;  // parts before the last
  std::size_t at = 0;
  std::uint64_t last = 0;
  for (;;) {
    if (at >= text.size() || !is_digit(text[at])) return std::nullopt;
    const auto v = address_part(text, at);
    if (!v) return std::nullopt;
    if (at < text.size() && text[at] == '.') {
      if (n > 2 || *v > 0xFF) return std::nullopt;
      parts[n++] = static_cast<std::uint32_t>(*v);
      ++at;
      continue;
    }
    last = *v;
    break;
  }
  if (at < text.size() && !is_ascii_space(text[at])) return std::nullopt;
  if (last > kLastPartMax[n]) return std::nullopt;
  std::uint32_t address = static_cast<std::uint32_t>(last);
  for (std::size_t i = 0; i < n; ++i) address |= parts[i] << (24 - 8 * i);
  return address;
}

std::string dotted_quad(std::uint32_t a) {
  return std::to_string(a >> 24) + "." + std::to_string((a >> 16) & 0xFF) + "." + std::to_string((a >> 8) & 0xFF) +
         "." + std::to_string(a & 0xFF);
}

namespace {

// The value of the last `key=` option of a URL's query ("" when absent), as liblcm reads it.
std::optional<std::string_view> last_option(std::string_view url, std::string_view key) {
  const auto q = url.find('?');
  if (q == std::string_view::npos) return std::nullopt;
  std::optional<std::string_view> found;
  std::string_view options = url.substr(q + 1);
  while (!options.empty()) {
    const auto amp = options.find('&');
    const auto kv = options.substr(0, amp);
    if (kv.size() > key.size() && kv.substr(0, key.size()) == key && kv[key.size()] == '=')
      found = kv.substr(key.size() + 1);
    options = amp == std::string_view::npos ? std::string_view() : options.substr(amp + 1);
  }
  return found;
}

// "host" of "scheme://host:port?..." (without the port).
std::string_view url_host(std::string_view url, std::size_t scheme_size) {
  const auto q = url.find('?');
  const auto host_port =
      url.substr(scheme_size, q == std::string_view::npos ? std::string_view::npos : q - scheme_size);
  return host_port.substr(0, host_port.find(':'));
}

}  // namespace

std::optional<std::string> lcm_reaches_beyond_host(std::string_view url) {
  constexpr std::string_view kUdpm = "udpm://", kTcpq = "tcpq://", kMemq = "memq://", kFile = "file://";
  if (url.substr(0, kMemq.size()) == kMemq || url.substr(0, kFile.size()) == kFile) return std::nullopt;
  if (url.substr(0, kTcpq.size()) == kTcpq) {
    const auto host = url_host(url, kTcpq.size());
    const auto a = parse_inet_aton(host);
    if (host == "localhost" || (a && (*a >> 24) == 127)) return std::nullopt;
    return "it connects to the LCM server " + std::string(host.empty() ? "(default)" : host) +
           ", which relays what anyone connected to it sends";
  }
  if (url.substr(0, kUdpm.size()) != kUdpm)
    return "its provider is none of udpm, tcpq, memq, file: oegw cannot tell who reaches it";
  const auto host = url_host(url, kUdpm.size());
  const auto group = parse_inet_aton(host.empty() ? std::string_view("239.255.76.67") : host);
  const std::string_view ttl = last_option(url, "ttl").value_or("0");
  if (ttl != "0")
    return "its ttl " + std::string(ttl) + " makes it a network's group: every device there may send to it";
  if (!group || *group != 0xE0000001u)
    return "its group " + (group ? dotted_quad(*group) : std::string(host)) +
           " is joined on the interface the routing table picks and announced there by IGMP: a device on that "
           "network may send to it (only 224.0.0.1 with ttl=0 is announced nowhere)";
  return std::nullopt;
}

std::optional<std::uint32_t> udpm_group(std::string_view url) {
  constexpr std::string_view kUdpm = "udpm://";
  if (url.substr(0, kUdpm.size()) != kUdpm) return std::nullopt;
  const auto host = url_host(url, kUdpm.size());
  return parse_inet_aton(host.empty() ? std::string_view("239.255.76.67") : host);
}

std::optional<std::string> lcm_route_problem(std::string_view url) {
  const auto group = udpm_group(url);
  if (!group) return std::nullopt;
  const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return std::string("cannot open a UDP socket (") + std::strerror(errno) + ")";
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_addr.s_addr = htonl(*group);
  to.sin_port = htons(7667);  // the route does not depend on the port
  const int rc = ::connect(fd, reinterpret_cast<const sockaddr*>(&to), sizeof to);
  const int e = errno;
  ::close(fd);
  if (rc == 0) return std::nullopt;
  return "no route to " + dotted_quad(*group) + " (" + std::strerror(e) + ")";
}

std::string lcm_route_command(std::string_view url, std::string_view device) {
  const std::string_view ttl = last_option(url, "ttl").value_or("0");
  if (ttl == "0") return "ip route add 224.0.0.0/4 dev lo";
  return "ip route add 224.0.0.0/4 dev " +
         (device.empty() ? std::string("<the cab network's interface>") : std::string(device));
}

std::optional<LinkLocalSend> link_local_send(std::string_view url) {
  constexpr std::string_view kScheme = "udpm://";
  if (url.substr(0, kScheme.size()) != kScheme) return std::nullopt;
  const auto q = url.find('?');
  const auto host_port =
      url.substr(kScheme.size(), q == std::string_view::npos ? std::string_view::npos : q - kScheme.size());
  const auto host = host_port.substr(0, host_port.find(':'));
  const auto group = parse_inet_aton(host);
  if (!group || (*group & 0xFFFFFF00u) != 0xE0000000u) return std::nullopt;
  std::string_view ttl = "0";
  if (q != std::string_view::npos) {
    std::string_view options = url.substr(q + 1);
    while (!options.empty()) {
      const auto amp = options.find('&');
      const auto kv = options.substr(0, amp);
      if (kv.substr(0, 4) == "ttl=") ttl = kv.substr(4);
      options = amp == std::string_view::npos ? std::string_view() : options.substr(amp + 1);
    }
  }
  if (ttl == "0") return std::nullopt;
  return LinkLocalSend{dotted_quad(*group), std::string(ttl)};
}

}  // namespace oegw::publish
