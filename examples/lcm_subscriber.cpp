// A minimal LCM subscriber for oegw's channels: copy it as a start.
//
//   lcm_subscriber [--count N] [--timeout SECONDS] [--url URL] [--channel REGEX]
//
// Defaults: URL udpm://224.0.0.1:7667?ttl=0 (multicast that never leaves the host), channels
// OEGW_JOYSTICK_[0-9]+. Each message is decoded with the type its channel carries (lcm_print.hpp)
// and printed on one line (a status: its line, then one per sub-device and upstream node):
//   joystick instance=1 status=valid seq=7 ts_us=123 x=100 y=-5 z=0 buttons=0x01 memory=0x00 rx_us=130
// (rx_us: CLOCK_MONOTONIC microseconds at reception, comparable with ts_us on this host). A message
// that does not decode is said on stderr. Exits 0 after N messages (or at the timeout when no
// --count is given), 3 when the timeout comes first, 2 for a command line it refuses, 1 when the
// URL cannot be opened. A timeout with nothing received says on stderr what it waited for and the
// likely cause (say_nothing_received).
#include <getopt.h>
#include <lcm/lcm.h>
#include <sys/select.h>

#include <cstdio>
#include <ctime>
#include <string>

#include "example_args.h"
#include "lcm_print.hpp"

namespace {

struct Options {
  long count = -1;  // -1: until the timeout
  double timeout_s = 10.0;
  const char* url = "udpm://224.0.0.1:7667?ttl=0";
  const char* channel = "OEGW_JOYSTICK_[0-9]+";
};

void usage(std::FILE* to, const char* prog) {
  std::fprintf(to,
               "usage: %s [--count N] [--timeout SECONDS] [--url URL] [--channel REGEX]\n"
               "Prints what the gateway publishes on LCM, one line per message.\n"
               "  --count N         exit 0 after N messages (exit 3 if the timeout comes first)\n"
               "  --timeout S       stop after S seconds (default 10)\n"
               "  --url URL         the gateway's publish.lcm.url (default udpm://224.0.0.1:7667?ttl=0)\n"
               "  --channel REGEX   the channels (default OEGW_JOYSTICK_[0-9]+; the demo's: OEGW_DEMO_...;\n"
               "                    OEGW_STATUS for the status, OEGW_.* for everything)\n"
               "  --help            this text\n",
               prog);
}

int take(const char* prog, int c, const char* value, void* ctx) {
  auto* o = static_cast<Options*>(ctx);
  switch (c) {
    case 'c': return example_parse_long(prog, "--count", value, 1, 1000000000L, &o->count);
    case 't': return example_parse_seconds(prog, "--timeout", value, &o->timeout_s);
    case 'u': o->url = value; return 1;
    case 'C': o->channel = value; return 1;
    default: return 0;
  }
}

const option longs[] = {{"count", required_argument, nullptr, 'c'}, {"timeout", required_argument, nullptr, 't'},
                        {"url", required_argument, nullptr, 'u'},   {"channel", required_argument, nullptr, 'C'},
                        {"help", no_argument, nullptr, 'h'},        {nullptr, 0, nullptr, 0}};

long long monotonic_us() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<long long>(ts.tv_sec) * 1000000LL + ts.tv_nsec / 1000;
}

long received = 0;

void on_message(const lcm_recv_buf_t* rbuf, const char* channel, void* /*user*/) {
  const long long rx = monotonic_us();
  const oegw_examples::Kind kind = oegw_examples::kind_of(channel);
  const auto lines = oegw_examples::describe(kind, rbuf->data, rbuf->data_size);
  if (lines.empty()) {
    std::fprintf(stderr, "%s: %u bytes that do not decode as %s\n", channel, static_cast<unsigned>(rbuf->data_size),
                 oegw_examples::lcm_type_name(kind));
    return;
  }
  std::printf("%s rx_us=%lld\n", lines[0].c_str(), rx);
  for (std::size_t i = 1; i < lines.size(); ++i) std::printf("%s\n", lines[i].c_str());
  std::fflush(stdout);
  ++received;
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
  lcm_subscribe(lcm, o.channel, &on_message, nullptr);
  std::printf("ready\n");
  std::fflush(stdout);

  const int fd = lcm_get_fileno(lcm);
  const long long deadline = monotonic_us() + static_cast<long long>(o.timeout_s * 1e6);
  while (o.count < 0 || received < o.count) {
    const long long left = deadline - monotonic_us();
    if (left <= 0) break;
    fd_set fds;
    FD_ZERO(&fds);
    FD_SET(fd, &fds);
    timeval tv{static_cast<time_t>(left / 1000000), static_cast<suseconds_t>(left % 1000000)};
    if (select(fd + 1, &fds, nullptr, nullptr, &tv) > 0) lcm_handle(lcm);
  }
  lcm_destroy(lcm);
  const char* prog = example_prog(argv[0]);
  if (received == 0) {
    // The demo's channels for the ones asked for: its prefix OEGW_DEMO_ where a gateway's OEGW_ is.
    const std::string channel = o.channel;
    std::string demo;
    if (channel.rfind("OEGW_DEMO_", 0) != 0)
      demo = "--channel '" + (channel.rfind("OEGW_", 0) == 0 ? "OEGW_DEMO_" + channel.substr(5) : "OEGW_DEMO_.*") + "'";
    oegw_examples::say_nothing_received(prog, channel, o.url, o.timeout_s, demo);
  } else if (o.count >= 0 && received < o.count) {
    std::fprintf(stderr, "%s: %ld of the %ld messages within %g s\n", prog, received, o.count, o.timeout_s);
  }
  return (o.count >= 0 && received < o.count) ? EXAMPLE_EXIT_INCOMPLETE : EXAMPLE_EXIT_OK;
}
