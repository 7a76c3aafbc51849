// libFuzzer target for the mapping-file loader as `oegw check` and `oegw run` use it: the input
// is the file's text, read with the real drivers' signal catalogue. Invariants (trap on breach):
// the result is a complete Config or errors, never both and never neither; every error is
// "file:line:column: ..." with line and column from 1; a Config that loads builds the upstream
// device's configuration and dictionary (nothing `check` accepts fails at start).
// Seeds: config/*.yaml and tests/fixtures/*.yaml (run from the source directory, where their
// relative EDS paths resolve); dictionary: mapping.dict.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "gateway/oe_device.hpp"
#include "gateway/runtime_config.hpp"
#include "mapping/config.hpp"
#include "tests/fuzz/fuzz_support.hpp"

using namespace oegw;
using fuzz::catalogue;
using fuzz::check;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const auto r = mapping::load_config_text(text, "f.yaml", catalogue);
  check(r.ok() != !r.errors.empty());
  for (const auto& e : r.errors) {
    check(e.where.line >= 1 && e.where.column >= 1 && !e.message.empty());
    check(e.str().rfind("f.yaml:", 0) == 0);
  }
  if (r.ok()) {
    const auto cfg = gateway::device_config(*r.config, std::filesystem::path("/nonexistent/oegw-fuzz.store"));
    gateway::OeDevice device(cfg, [](const canopen::CanFrame&) {});
    check(device.od().find(0x1000) != nullptr);
  }
  return 0;
}
