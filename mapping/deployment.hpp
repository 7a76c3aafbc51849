// What `oegw check` and `oegw run` ask of a mapping file beyond what load_config() checks: the
// settings of a gateway on a real cab controller. The embedded demo and the tests load the same
// files through load_config() with the in-process bus (`interface: virtual`), so these checks
// are apart from the loader: only the two commands that face a cab apply them
// (docs/reference/mapping-file.md#checked-before-a-run).
#pragma once

#include <vector>

#include "mapping/config.hpp"

namespace oegw::mapping {

// Two kinds of finding (docs/reference/mapping-file.md#checked-before-a-run): facts of the FILE,
// wrong on any machine, and facts of THIS MACHINE (its folders, groups, files as they are now),
// which only the machine the file is for can settle. `oegw check FILE` refuses the first and
// prints the second as warnings of their own section, so that a file is checked on an
// integrator's laptop as well as on the cab controller; `oegw check --here FILE` and `oegw run`
// (on the machine itself) refuse both.

// The file's settings `oegw run` refuses, each at its value's place: an interface name the kernel
// refuses (empty, longer than IFNAMSIZ-1 = 15 bytes, '/', ':' or whitespace in it, "." or ".."),
// `virtual` (the demo's bus), one interface for both buses.
[[nodiscard]] std::vector<Diagnostic> deployment_errors(const Config& c);

// What `oegw run` refuses of this machine as it finds it at start, each at its setting's place:
// an upstream store whose folder does not exist or that is a symbolic link (never followed,
// canopen/301/storage.hpp); a record.dir one of whose folders is a file; of an enabled control
// socket, a `control.group` the machine lacks, a socket folder run cannot make (neither it nor
// its parent exists, or it is no folder), a file at the socket's path that is no socket.
[[nodiscard]] std::vector<Diagnostic> machine_errors(const Config& c);

// Likely mistakes of the file that still run (`oegw check` prints them, exit 0): a mandatory
// sub-device without a heartbeat (its loss is seen only by its PDO time-out), a sub-device no FE
// uses, LCM commands on a URL that reaches beyond this host.
[[nodiscard]] std::vector<Diagnostic> deployment_warnings(const Config& c);

// Likely mistakes of this machine that still run: an upstream store in a folder every user may
// write (S_IWOTH: anyone can place its parameters).
[[nodiscard]] std::vector<Diagnostic> machine_warnings(const Config& c);

// In the file's order (line, then column); the order of equal places kept.
void sort_by_place(std::vector<Diagnostic>& d);

}  // namespace oegw::mapping
