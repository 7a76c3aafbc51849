#include "cli/button_bits_command.hpp"

#include <cstdio>
#include <memory>

#include "gateway/programs.hpp"
#include "gateway/run_on_bus.hpp"
#include "subdevices/mcb402_commissioning.hpp"

namespace oegw::cli {

int run_find_button_bits(const FindButtonBitsOptions& o) {
  using namespace canopen;
  using namespace canopen::io;
  auto port = gateway::open_tool_interface(o.interface);
  if (!port) return exit_code::kCannotStart;
  SocketCanTransport* bus = port.get();
  subdevices::ButtonBitsFinder::Options fo;
  fo.node = NodeId{static_cast<std::uint8_t>(o.node)};
  fo.step_timeout = std::chrono::duration_cast<Duration>(std::chrono::duration<double>(o.timeout_s));
  // Each line as it comes (a user at a terminal, or a script answering the prompts).
  subdevices::ButtonBitsFinder finder(
      fo, [bus](const CanFrame& f) { (void)bus->send(f); },
      [](const std::string& line) {
        std::printf("%s\n", line.c_str());
        std::fflush(stdout);
      });
  gateway::run_on_bus(*port, finder);
  if (!finder.result()) {
    if (finder.error().empty()) std::fprintf(stderr, "interrupted: no button_bits found\n");
    return exit_code::kBadFile;
  }
  std::printf("%s\n", subdevices::ButtonBitsFinder::yaml_line(*finder.result()).c_str());
  std::printf("(mapping file: options: { %s }; on a command line: %s)\n",
              subdevices::ButtonBitsFinder::yaml_line(*finder.result()).c_str(),
              subdevices::ButtonBitsFinder::command_line_option(*finder.result()).c_str());
  return exit_code::kOk;
}

}  // namespace oegw::cli
