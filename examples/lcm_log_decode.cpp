// Decodes an LCM log (as recorded by `lcm-logger`) with oegw's LCM types and prints the joystick
// samples in the same format as lcm_subscriber, each gateway status (a line, then one per
// sub-device and per upstream node whose EMCYs it consumed), and a count of the others:
//   lcm_log_decode FILE [CHANNEL_PREFIX]      (prefix default OEGW_)
//   status seq=3 upstream=operational subdevices=1 emcys=1 refused=0
//     subdevice right_grip node=11h state=operational emcys=2 last=1000h reg=00h msef=21 00 ff ff ff ts_us=4100
//     upstream_emcy node=05h emcys=1 last=8130h reg=11h msef=00 00 00 00 00 ts_us=5000
#include <lcm/eventlog.h>

#include <cstdint>
#include <cstdio>
#include <string>

#include "oegw/gateway_status_t.hpp"
#include "oegw/joystick_t.hpp"

namespace {
// " emcys=N last=CODEh reg=REGh msef=.. .. .. .. .. ts_us=T"
void print_emcy(std::int64_t count, const oegw::emcy_t& e) {
  std::printf(" emcys=%lld last=%04Xh reg=%02Xh msef=%02x %02x %02x %02x %02x ts_us=%lld\n", static_cast<long long>(count),
              static_cast<unsigned>(static_cast<std::uint16_t>(e.code)), static_cast<unsigned>(e.error_register),
              static_cast<unsigned>(e.msef[0]), static_cast<unsigned>(e.msef[1]), static_cast<unsigned>(e.msef[2]),
              static_cast<unsigned>(e.msef[3]), static_cast<unsigned>(e.msef[4]), static_cast<long long>(e.timestamp_us));
}
}  // namespace

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
        for (const auto& d : s.subdevices) {
          std::printf("  subdevice %s node=%02Xh state=%s", d.name.c_str(), static_cast<unsigned>(d.node_id), d.state.c_str());
          print_emcy(d.emcy_count, d.last_emcy);
        }
        for (const auto& u : s.upstream_emcys) {
          std::printf("  upstream_emcy node=%02Xh", static_cast<unsigned>(u.node_id));
          print_emcy(u.count, u.last);
        }
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
