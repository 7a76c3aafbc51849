// Prints what the gateway's status (channel <prefix>STATUS) says as it changes: copy it as a start.
//
//   lcm_status [--timeout SECONDS] [--every] [--url URL] [--prefix PREFIX]
//
// The same lines as dds_status, one per change (the first status: every line):
//   upstream state=operational
//   subdevice right_grip node=11h state=operational vendor=0000012Eh product=... name="MFG" err=00h
//   emcy right_grip node=11h count=1 last=8130h reg=11h msef=00 00 00 00 00 ts_us=5000
//   upstream_emcy node=05h count=1 last=8130h reg=11h msef=01 02 03 04 05 ts_us=5000
//   active_emcys 7000h
//   refused_commands 2
// and with --every a line per status message first:
//   status seq=12 upstream=operational subdevices=5 active=none refused=0
// Exits 0 at the timeout (default: none, Ctrl-C) when a status came, 3 when none came, 2 for a
// command line it refuses, 1 when the URL cannot be opened.
#include <lcm/lcm.h>
#include <sys/select.h>

#include <cctype>
#include <csignal>
#include <cstdio>
#include <ctime>
#include <map>
#include <string>

#include "example_args.h"
#include "lcm_print.hpp"
#include "oegw/gateway_status_t.hpp"

namespace {

namespace ex = oegw_examples;

struct Options {
  double timeout_s = 0;  // 0: none
  bool every = false;
  const char* url = "udpm://224.0.0.1:7667?ttl=0";
  const char* prefix = "OEGW_";
};

void usage(std::FILE* to, const char* prog) {
  std::fprintf(to,
               "usage: %s [--timeout SECONDS] [--every] [--url URL] [--prefix PREFIX]\n"
               "Prints the gateway's status (channel PREFIX + STATUS) as it changes: sub-device states and\n"
               "identities, EMCYs, the gateway's active EMCYs, refused commands; one line each.\n"
               "  --timeout S       stop after S seconds (default: run until Ctrl-C)\n"
               "  --every           also a line for every status message\n"
               "  --url URL         the gateway's publish.lcm.url (default udpm://224.0.0.1:7667?ttl=0)\n"
               "  --prefix PREFIX   its publish.lcm.channel_prefix (default OEGW_; the demo's: OEGW_DEMO_)\n"
               "  --help            this text\n",
               prog);
}

int take(const char* prog, int c, const char* value, void* ctx) {
  auto* o = static_cast<Options*>(ctx);
  switch (c) {
    case 't': return example_parse_seconds(prog, "--timeout", value, &o->timeout_s);
    case 'e': o->every = true; return 1;
    case 'u': o->url = value; return 1;
    case 'p': o->prefix = value; return 1;
    default: return 0;
  }
}

const option longs[] = {{"timeout", required_argument, nullptr, 't'}, {"every", no_argument, nullptr, 'e'},
                        {"url", required_argument, nullptr, 'u'},     {"prefix", required_argument, nullptr, 'p'},
                        {"help", no_argument, nullptr, 'h'},          {nullptr, 0, nullptr, 0}};

// What the last status said, to print only what changed.
struct Seen {
  bool any = false;
  std::string upstream, active;
  std::int64_t refused = 0;
  std::map<std::string, std::string> subdevice_lines;
  std::map<std::string, std::int64_t> subdevice_emcys;
  std::map<int, std::int64_t> upstream_emcys;
};

void print_subdevice(const oegw::subdevice_state_t& d, Seen& seen) {
  const unsigned node = d.node_id;
  char head[256];
  std::snprintf(head, sizeof head, "subdevice %s node=%02Xh state=%s", d.name.c_str(), node, d.state.c_str());
  const std::string line = head + ex::identity_text(d.identity);
  auto& last_line = seen.subdevice_lines[d.name];
  if (last_line != line) std::printf("%s\n", line.c_str());
  last_line = line;
  auto& last_count = seen.subdevice_emcys[d.name];
  if (d.emcy_count > 0 && last_count != d.emcy_count)
    std::printf("emcy %s node=%02Xh count=%lld%s\n", d.name.c_str(), node, static_cast<long long>(d.emcy_count),
                ex::emcy_text(d.last_emcy).c_str());
  last_count = d.emcy_count;
}

void print_status(const oegw::gateway_status_t& s, bool every, Seen& seen) {
  std::string active;
  for (const auto code : s.active_emcys) {
    char b[8];
    std::snprintf(b, sizeof b, "%04Xh", static_cast<unsigned>(static_cast<std::uint16_t>(code)));
    active += (active.empty() ? "" : ",") + std::string(b);
  }
  if (active.empty()) active = "none";
  if (every)
    std::printf("status seq=%u upstream=%s subdevices=%d active=%s refused=%lld\n", static_cast<std::uint32_t>(s.seq),
                s.upstream_state.c_str(), s.n_subdevices, active.c_str(), static_cast<long long>(s.refused_commands));
  if (!seen.any || seen.upstream != s.upstream_state) std::printf("upstream state=%s\n", s.upstream_state.c_str());
  for (const auto& d : s.subdevices) print_subdevice(d, seen);
  for (const auto& u : s.upstream_emcys) {
    auto& last = seen.upstream_emcys[u.node_id];
    if (last != u.count)
      std::printf("upstream_emcy node=%02Xh count=%lld%s\n", static_cast<unsigned>(u.node_id),
                  static_cast<long long>(u.count), ex::emcy_text(u.last).c_str());
    last = u.count;
  }
  if (!seen.any || seen.active != active) std::printf("active_emcys %s\n", active.c_str());
  if (!seen.any || seen.refused != s.refused_commands)
    std::printf("refused_commands %lld\n", static_cast<long long>(s.refused_commands));
  seen.upstream = s.upstream_state;
  seen.active = active;
  seen.refused = s.refused_commands;
  seen.any = true;
  std::fflush(stdout);
}

struct Receiver {
  bool every;
  Seen seen;
};

void on_status(const lcm_recv_buf_t* rbuf, const char* channel, void* user) {
  auto* r = static_cast<Receiver*>(user);
  oegw::gateway_status_t s;
  if (s.decode(rbuf->data, 0, static_cast<int>(rbuf->data_size)) != static_cast<int>(rbuf->data_size)) {
    std::fprintf(stderr, "%s: %u bytes that do not decode as oegw.gateway_status_t\n", channel,
                 static_cast<unsigned>(rbuf->data_size));
    return;
  }
  print_status(s, r->every, r->seen);
}

volatile std::sig_atomic_t stop = 0;
void on_signal(int) { stop = 1; }

long long monotonic_us() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<long long>(ts.tv_sec) * 1000000LL + ts.tv_nsec / 1000;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  if (const int exit = example_parse_options(argc, argv, longs, take, nullptr, usage, &o); exit >= 0) return exit;
  lcm_t* lcm = lcm_create(o.url);
  if (lcm == nullptr) {
    std::fprintf(stderr, "%s: cannot open LCM URL %s\n", example_prog(argv[0]), o.url);
    return EXAMPLE_EXIT_SETUP;
  }
  Receiver r{o.every, {}};
  // The channel name exactly (lcm_subscribe takes a regular expression: the prefix is escaped).
  std::string channel;
  for (const char* p = o.prefix; *p != 0; ++p)
    channel += std::string(std::isalnum(static_cast<unsigned char>(*p)) || *p == '_' ? "" : "\\") + *p;
  lcm_subscribe(lcm, (channel + "STATUS").c_str(), &on_status, &r);
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  std::printf("ready\n");
  std::fflush(stdout);

  const int fd = lcm_get_fileno(lcm);
  const long long deadline = o.timeout_s > 0 ? monotonic_us() + static_cast<long long>(o.timeout_s * 1e6) : -1;
  while (stop == 0 && (deadline < 0 || monotonic_us() < deadline)) {
    fd_set fds;
    FD_ZERO(&fds);
    FD_SET(fd, &fds);
    timeval tv{0, 100000};  // woken every 100 ms at least, to see a signal and the timeout
    if (select(fd + 1, &fds, nullptr, nullptr, &tv) > 0) lcm_handle(lcm);
  }
  lcm_destroy(lcm);
  if (!r.seen.any)
    oegw_examples::say_nothing_received(example_prog(argv[0]), channel + "STATUS", o.url, o.timeout_s,
                                        std::string(o.prefix) == "OEGW_DEMO_" ? "" : "--prefix OEGW_DEMO_");
  return r.seen.any ? EXAMPLE_EXIT_OK : EXAMPLE_EXIT_INCOMPLETE;
}
