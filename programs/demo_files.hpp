// The demo's mapping file and EDS files, built into the program so `oegw demo` runs anywhere.
#pragma once

namespace oegw::programs::demo_files {
extern const char* const kDemoYaml;    // config/demo.yaml
extern const char* const kPedalEds;    // subdevices/eds/generic_pedal.eds
extern const char* const kClusterEds;  // subdevices/eds/button_cluster.eds
}  // namespace oegw::programs::demo_files
