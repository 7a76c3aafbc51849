#include "cli/signals.hpp"

#include <cstdio>
#include <memory>

#include "cli/app.hpp"
#include "cli/button_bits_command.hpp"
#include "cli/exit_codes.hpp"
#include "cli/signals_command.hpp"

namespace oegw::cli {

void register_signals(CLI::App& app) {
  struct Options {
    cli::SignalsOptions signals;
    // Commissioning an MCB-402: its button wiring read off the board
    // (docs/design/device-documents.md#mcb-402-button-bits-a-required-commissioning-choice).
    bool find_button_bits = false;
    cli::FindButtonBitsOptions find_bits;
  };
  auto o = std::make_shared<Options>();
  auto* cmd =
      app.add_subcommand(
             "signals",
             "Every driver's signals (name, direction, kind, range, unit, neutral) and options, from the drivers")
          ->group(kDailyGroup);
  cmd->add_option("driver", o->signals.driver, "One driver: elobau-mfg, mcb402, novotechnik-406, cia401");
  cmd->add_option("-o,--option", o->signals.options,
                  "A driver option key=value, as in the mapping file (e.g. detent=clamp); repeatable");
  cmd->add_option("--eds", o->signals.eds, "cia401: the EDS file whose signals to list");
  cmd->add_flag("--markdown", o->signals.markdown, "Markdown tables, as in docs/reference/drivers.md");
  cmd->add_flag("--find-button-bits", o->find_button_bits,
                "mcb402: watch the board's TPDO1 on -i IF, ask for BP1..BP7 in turn and print its button_bits line");
  cmd->add_option("-i,--interface", o->find_bits.interface, "--find-button-bits: the sub-devices' CAN interface");
  cmd->add_option("--node", o->find_bits.node, "--find-button-bits: the board's node-ID (default 3)")
      ->check(CLI::Range(1, 127));
  cmd->add_option("--timeout", o->find_bits.timeout_s,
                  "--find-button-bits: seconds to wait for each press (default 60)")
      ->check(CLI::Range(1.0, 3600.0));
  cmd->callback([o] {
    if (!o->find_button_bits) finish(cli::run_signals(o->signals));
    if (o->signals.driver != "mcb402" || o->find_bits.interface.empty()) {
      std::fprintf(stderr, "--find-button-bits: expected `oegw signals mcb402 --find-button-bits -i IF [--node N]`\n");
      finish(exit_code::kUsage);
    }
    finish(cli::run_find_button_bits(o->find_bits));
  });
}

}  // namespace oegw::cli
