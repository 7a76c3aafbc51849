// Text for every message oegw publishes or takes on LCM, shared by lcm_subscriber, lcm_log_decode
// and lcm_status. The type of a message follows from its channel's name
// (docs/guides/dds-lcm.md#lcm-channels): <prefix>JOYSTICK_n, PEDAL_n, WHEEL_n, ENCODER_n,
// BUTTONS_n, INDICATORS_n, DISPLAY_n, STATUS.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "oegw/emcy_t.hpp"
#include "oegw/subdevice_identity_t.hpp"

namespace oegw_examples {

enum class Kind { Joystick, Pedal, Wheel, Encoder, Buttons, Indicators, Display, Status, Unknown };

// The kind a channel carries, from the end of its name; Unknown for a channel oegw does not use.
Kind kind_of(const std::string& channel);
const char* lcm_type_name(Kind kind);  // "oegw.joystick_t", ...

// The lines of one message (a status: its line, then one per sub-device and per upstream node);
// empty when it does not decode as its kind's type.
std::vector<std::string> describe(Kind kind, const void* data, std::size_t size);

// " code=8130h reg=11h msef=01 02 03 04 05 ts_us=5000"
std::string emcy_text(const oegw::emcy_t& e);
// What a sub-device said about itself at its last boot, the fields its `present` mask has:
// " vendor=0000012Eh product=... revision=... serial=... name=\"...\" hw=\"...\" sw=\"...\" err=00h",
// or " identity=none".
std::string identity_text(const oegw::subdevice_identity_t& id);

// Said on stderr by a reader whose SECONDS (0: stopped by a signal) passed with nothing on the
// channels matching CHANNELS (a regular expression) at URL: what it waited for, then the likeliest
// cause. `oegw demo` publishes under its own prefix, OEGW_DEMO_, a gateway under its
// publish.lcm.channel_prefix (default OEGW_), so a reader left at the default hears nothing from
// the demo (docs/guides/dds-lcm.md#the-demo). DEMO_OPTION is the option that reads the demo's
// channels (e.g. "--prefix OEGW_DEMO_"), empty when CHANNELS already are the demo's.
void say_nothing_received(const char* prog, const std::string& channels, const char* url, double seconds,
                          const std::string& demo_option);

}  // namespace oegw_examples
