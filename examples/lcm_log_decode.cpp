// Decodes an LCM log (as recorded by `lcm-logger`) with oegw's LCM types and prints the joystick
// samples in the same format as lcm_subscriber, and a count of the others:
//   lcm_log_decode FILE [CHANNEL_PREFIX]      (prefix default OEGW_)
#include <lcm/eventlog.h>

#include <cstdint>
#include <cstdio>
#include <string>

#include "oegw/gateway_status_t.hpp"
#include "oegw/joystick_t.hpp"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s FILE [CHANNEL_PREFIX]\n", argv[0]);
    return 1;
  }
  const std::string prefix = argc > 2 ? argv[2] : "OEGW_";
  lcm_eventlog_t* log = lcm_eventlog_create(argv[1], "r");
  if (log == nullptr) {
    std::fprintf(stderr, "cannot open LCM log %s\n", argv[1]);
    return 1;
  }
  static const char* const names[] = {"valid", "error", "not_available", "stale", "offline"};
  long joysticks = 0, statuses = 0, others = 0, bad = 0;
  for (lcm_eventlog_event_t* ev = lcm_eventlog_read_next_event(log); ev != nullptr;
       ev = lcm_eventlog_read_next_event(log)) {
    const std::string ch(ev->channel, ev->channellen);
    if (ch.rfind(prefix + "JOYSTICK_", 0) == 0) {
      oegw::joystick_t j;
      if (j.decode(ev->data, 0, static_cast<int>(ev->datalen)) < 0) {
        ++bad;
      } else {
        std::printf("joystick instance=%u status=%s seq=%u ts_us=%lld x=%d y=%d z=%d buttons=0x%02x memory=0x%02x\n",
                    static_cast<unsigned>(static_cast<std::uint8_t>(j.instance)),
                    j.status >= 0 && j.status <= 4 ? names[j.status] : "?", static_cast<unsigned>(j.seq),
                    static_cast<long long>(j.timestamp_us), j.x, j.y, j.z, static_cast<unsigned>(j.buttons),
                    static_cast<unsigned>(j.memory));
        ++joysticks;
      }
    } else if (ch == prefix + "STATUS") {
      oegw::gateway_status_t s;
      if (s.decode(ev->data, 0, static_cast<int>(ev->datalen)) < 0) {
        ++bad;
      } else {
        std::printf("status seq=%u upstream=%s subdevices=%d emcys=%d refused=%lld\n", static_cast<unsigned>(s.seq),
                    s.upstream_state.c_str(), s.n_subdevices, s.n_active_emcys,
                    static_cast<long long>(s.refused_commands));
        ++statuses;
      }
    } else {
      ++others;
    }
    lcm_eventlog_free_event(ev);
  }
  lcm_eventlog_destroy(log);
  std::printf("decoded joystick=%ld status=%ld other=%ld bad=%ld\n", joysticks, statuses, others, bad);
  return bad == 0 ? 0 : 3;
}
