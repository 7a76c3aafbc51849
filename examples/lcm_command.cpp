// Commands the gateway's indicators and displays over LCM (channels <prefix>INDICATORS_n,
// <prefix>DISPLAY_n): copy it as a start.
//
//   lcm_command indicators 1 --on 1,3          indicators 1 and 3 of indicators.1 on, the others off
//   lcm_command display 1 --set 1=100,2=-5     display.1 parameters 1 and 2, the others 0
//   [--url URL] [--prefix PREFIX]
//
// LCM is best effort and has no discovery: the message is sent once, and nothing says whether a
// gateway got it (lcm_status shows refused_commands rise when the FE's `sources` leave lcm out).
// Exits 0 when sent, 2 for a command line it refuses, 1 when the URL cannot be opened or the
// message cannot be sent.
#include <lcm/lcm.h>

#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "command_args.h"
#include "oegw/display_command_t.hpp"
#include "oegw/indicator_command_t.hpp"

namespace {

struct Options {
  command_args command{};
  const char* url = "udpm://224.0.0.1:7667?ttl=0";
  const char* prefix = "OEGW_";
};

void usage(std::FILE* to, const char* prog) {
  std::fprintf(to,
               "usage: %s " COMMAND_USAGE
               "\n"
               "       [--url URL] [--prefix PREFIX]\n"
               "Sends one command to the gateway's indicators or display over LCM.\n" COMMAND_HELP
               "  --url URL         the gateway's publish.lcm.url (default udpm://224.0.0.1:7667?ttl=0)\n"
               "  --prefix PREFIX   its publish.lcm.channel_prefix (default OEGW_; the demo's: OEGW_DEMO_)\n"
               "  --help            this text\n",
               prog);
}

int take(const char* prog, int c, const char* value, void* ctx) {
  auto* o = static_cast<Options*>(ctx);
  if (const int command = command_take(prog, c, value, &o->command); command >= 0) return command;
  if (c == 'u') o->url = value;
  if (c == 'p') o->prefix = value;
  return c == 'u' || c == 'p';
}

int positional(const char* prog, int index, const char* arg, void* ctx) {
  return command_positional(prog, index, arg, &static_cast<Options*>(ctx)->command);
}

const option longs[] = {COMMAND_LONG,
                        {"url", required_argument, nullptr, 'u'},
                        {"prefix", required_argument, nullptr, 'p'},
                        {"help", no_argument, nullptr, 'h'},
                        {nullptr, 0, nullptr, 0}};

// The channel and the encoded message of the command.
std::pair<std::string, std::vector<std::uint8_t>> encode(const Options& o) {
  const command_args& a = o.command;
  const std::string n = std::to_string(a.instance);
  auto bytes = [](const auto& msg) {
    std::vector<std::uint8_t> out(static_cast<std::size_t>(msg.getEncodedSize()));
    msg.encode(out.data(), 0, static_cast<int>(out.size()));
    return out;
  };
  if (a.kind == COMMAND_INDICATORS) {
    oegw::indicator_command_t c;
    c.instance = static_cast<std::int8_t>(a.instance);
    c.indicators = static_cast<std::int64_t>(a.indicators);
    return {o.prefix + std::string("INDICATORS_") + n, bytes(c)};
  }
  oegw::display_command_t c;
  c.instance = static_cast<std::int8_t>(a.instance);
  std::memcpy(c.parameters, a.parameters, sizeof c.parameters);
  return {o.prefix + std::string("DISPLAY_") + n, bytes(c)};
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  const char* prog = example_prog(argv[0]);
  if (const int exit = example_parse_options(argc, argv, longs, take, positional, usage, &o); exit >= 0) return exit;
  if (!command_complete(prog, &o.command)) {
    usage(stderr, prog);
    return EXAMPLE_EXIT_USAGE;
  }
  lcm_t* lcm = lcm_create(o.url);
  if (lcm == nullptr) {
    std::fprintf(stderr, "%s: cannot open LCM URL %s\n", prog, o.url);
    return EXAMPLE_EXIT_SETUP;
  }
  const auto [channel, data] = encode(o);
  char text[512];
  command_text(text, sizeof text, &o.command);
  const int sent = lcm_publish(lcm, channel.c_str(), data.data(), static_cast<unsigned>(data.size()));
  lcm_destroy(lcm);
  if (sent != 0) {
    std::fprintf(stderr, "%s: %s: cannot send on %s\n", prog, text, channel.c_str());
    return EXAMPLE_EXIT_SETUP;
  }
  std::printf("sent %s on %s\n", text, channel.c_str());
  return EXAMPLE_EXIT_OK;
}
