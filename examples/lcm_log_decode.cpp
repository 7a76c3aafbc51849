// Decodes an LCM log (as recorded by `lcm-logger`) with oegw's LCM types: every channel the
// gateway publishes or takes (lcm_print.hpp), in the format of lcm_subscriber (without rx_us),
// and a summary of what it found:
//   lcm_log_decode FILE [CHANNEL_PREFIX]      (prefix default OEGW_; the demo's: OEGW_DEMO_)
//   joystick instance=1 status=valid seq=7 ts_us=123 x=100 y=-5 z=0 buttons=0x01 memory=0x00
//   status seq=3 upstream=operational subdevices=1 emcys=1 refused=0 active=7000h
//     subdevice right_grip node=11h state=operational emcys=2 last=1000h reg=00h msef=21 00 ff ff ff ts_us=4100
//     vendor=... upstream_emcy node=05h emcys=1 last=8130h reg=11h msef=00 00 00 00 00 ts_us=5000
//   decoded joystick=20 pedal=10 wheel=10 encoder=10 buttons=10 indicators=1 display=0 status=10 other=0 bad=0
// "other": channels outside the prefix or not oegw's; "bad": messages on an oegw channel that do
// not decode as its type (each also said on stderr). Exits 0, 3 when some were bad, 2 for a
// command line it refuses, 1 when the file cannot be read.
#include <getopt.h>
#include <lcm/eventlog.h>

#include <cstdio>
#include <string>

#include "example_args.h"
#include "lcm_print.hpp"

namespace {

namespace ex = oegw_examples;

void usage(std::FILE* to, const char* prog) {
  std::fprintf(to,
               "usage: %s FILE [CHANNEL_PREFIX]\n"
               "Prints every oegw message of an LCM log (lcm-logger's file), one line each, then a count.\n"
               "  CHANNEL_PREFIX    the gateway's publish.lcm.channel_prefix (default OEGW_; the demo's: OEGW_DEMO_)\n"
               "  --help            this text\n",
               prog);
}

// The counts of the summary, by kind (Kind::Unknown: "other").
struct Counts {
  long by_kind[static_cast<int>(ex::Kind::Unknown) + 1] = {};
  long bad = 0;
  void print() const {
    static const char* const names[] = {"joystick",   "pedal",   "wheel",  "encoder", "buttons",
                                        "indicators", "display", "status", "other"};
    std::printf("decoded");
    for (int k = 0; k <= static_cast<int>(ex::Kind::Unknown); ++k) std::printf(" %s=%ld", names[k], by_kind[k]);
    std::printf(" bad=%ld\n", bad);
  }
};

void decode_one(const lcm_eventlog_event_t& ev, const std::string& prefix, Counts& counts) {
  const std::string channel(ev.channel, static_cast<std::size_t>(ev.channellen));
  const ex::Kind kind = channel.rfind(prefix, 0) == 0 ? ex::kind_of(channel.substr(prefix.size())) : ex::Kind::Unknown;
  if (kind != ex::Kind::Unknown) {
    const auto lines = ex::describe(kind, ev.data, static_cast<std::size_t>(ev.datalen));
    if (lines.empty()) {
      std::fprintf(stderr, "event %lld on %s: %d bytes that do not decode as %s\n", static_cast<long long>(ev.eventnum),
                   channel.c_str(), static_cast<int>(ev.datalen), ex::lcm_type_name(kind));
      ++counts.bad;
      return;
    }
    for (const auto& l : lines) std::printf("%s\n", l.c_str());
  }
  ++counts.by_kind[static_cast<int>(kind)];
}

}  // namespace

int main(int argc, char** argv) {
  const char* prog = example_prog(argv[0]);
  static const option longs[] = {{"help", no_argument, nullptr, 'h'}, {nullptr, 0, nullptr, 0}};
  for (int c; (c = getopt_long(argc, argv, "", longs, nullptr)) != -1;) {
    if (c == 'h') {
      usage(stdout, prog);
      return EXAMPLE_EXIT_OK;
    }
    usage(stderr, prog);  // getopt said what is wrong
    return EXAMPLE_EXIT_USAGE;
  }
  const int args = argc - optind;
  if (args < 1 || args > 2) {
    if (args < 1) std::fprintf(stderr, "%s: no FILE given\n", prog);
    else example_unexpected(prog, argv[optind + 2]);
    usage(stderr, prog);
    return EXAMPLE_EXIT_USAGE;
  }
  const char* file = argv[optind];
  const std::string prefix = args > 1 ? argv[optind + 1] : "OEGW_";
  lcm_eventlog_t* log = lcm_eventlog_create(file, "r");
  if (log == nullptr) {
    std::fprintf(stderr, "%s: cannot open LCM log %s\n", prog, file);
    return EXAMPLE_EXIT_SETUP;
  }
  Counts counts;
  for (lcm_eventlog_event_t* ev = lcm_eventlog_read_next_event(log); ev != nullptr;
       ev = lcm_eventlog_read_next_event(log)) {
    decode_one(*ev, prefix, counts);
    lcm_eventlog_free_event(ev);
  }
  lcm_eventlog_destroy(log);
  counts.print();
  return counts.bad == 0 ? EXAMPLE_EXIT_OK : EXAMPLE_EXIT_INCOMPLETE;
}
