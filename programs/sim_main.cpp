// oegw-sim — simulated sub-devices (elobau MFG, MCB-402, Novotechnik CiA 406, generic CiA 401)
// on a SocketCAN interface, for bench-testing the gateway without hardware.
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include "programs/bench_programs.hpp"

int main(int argc, char** argv) {
  CLI::App app{"oegw-sim — simulated cab devices on a SocketCAN interface"};
  oegw::programs::SimOptions o;
  app.add_option("-i,--interface", o.interface, "SocketCAN interface")->required();
  app.add_flag("--motion", o.motion, "Sweep every axis and press the buttons in turn");
  app.add_flag("--commands", o.commands,
               "Read commands from standard input: '<device> <signal> <value>', '<device> silent on|off', "
               "'<device> heartbeat on|off', '<device> pdo on|off' (TPDOs stop; heartbeat and SDO go on), "
               "'<device> bootup on|off' (off: its boot-ups are lost), "
               "'<device> reboot', '<device> cable_break <axis 1..4> on|off' (MCB-402: EMCY 3120h), "
               "'<device> bus_off' (MCB-402, elobau), '<device> life_guarding' (MCB-402), "
               "'<device> error <code> on|off' (elobau 4001h), "
               "'<device> fault measurement|overflow|underflow|hardware|clear' (Novotechnik §9.1)");
  app.add_option(
         "devices", o.devices,
         "family:node[:key=value,...], e.g. elobau-mfg:0x11 mcb402:0x03 "
         "cia401:0x30:eds=subdevices/eds/generic_pedal.eds (options: name, heartbeat_ms, store, bootup=off (its "
         "boot-ups lost), eds; "
         "the corners of each document (docs/design/device-documents.md#corners-every-reading-a-document-permits): "
         "mcb402 wiring=1/2/3/4/5/7/6 (the bit of "
         "TPDO1 byte 2 each button BP1..BP7 sets; default the table's right-end reading 0/1/2/3/4/6/5), "
         "clear_after_break=0000h|none, power_on_1001h=00h|11h; elobau-mfg tpdo=change|timer, saved=yes|no, "
         "buttons=63 (2100h:01h), buttons_9_16=0; novotechnik-406 error_register_size=1|2, emcy_behaviour=0..3, "
         "has_6020h=yes|no, work_area_emcy=bits|enum, load=defaults|stored)")
      ->required();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 64;  // as oegw: a usage error is 64 (docs/reference/exit-codes.md)
  }
  spdlog::set_pattern("%^%l%$: %v");
  return oegw::programs::run_sim(o);
}
