// What `oegw check` and `oegw run` ask of a mapping file beyond what load_config() checks: the
// settings of a gateway on a real cab controller. The embedded demo and the tests load the same
// files through load_config() with the in-process bus (`interface: virtual`), so these checks
// are apart from the loader: only the two commands that face a cab apply them
// (docs/reference/mapping-file.md#checked-before-a-run).
#pragma once

#include <vector>

#include "mapping/config.hpp"

namespace oegw::mapping {

// The settings `oegw run` refuses, each at its value's place: an interface name the kernel
// refuses (empty, longer than IFNAMSIZ-1 = 15 bytes, '/', ':' or whitespace in it, "." or ".."),
// `virtual` (the demo's bus), one interface for both buses, an upstream store whose folder does
// not exist or that is a symbolic link (never followed, canopen/301/storage.hpp); of an enabled control socket (facts of this machine, as run finds them at start): a
// `control.group` the machine lacks, a socket folder run cannot make (neither it nor its parent
// exists, or it is no folder), a file at the socket's path that is no socket.
[[nodiscard]] std::vector<Diagnostic> deployment_errors(const Config& c);

// Likely mistakes that still run (`oegw check` prints them, exit 0): a mandatory sub-device
// without a heartbeat (its loss is seen only by its PDO time-out), a sub-device no FE uses, an
// upstream store in a folder every user may write (S_IWOTH: anyone can place its parameters).
[[nodiscard]] std::vector<Diagnostic> deployment_warnings(const Config& c);

}  // namespace oegw::mapping
