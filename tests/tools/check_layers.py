#!/usr/bin/env python3
"""The layer check: every `#include "..."` of the repository's sources against the table of which
layer may include which. Exit 0 when every include is declared, 1 with one line per undeclared
include:

    canopen/301/pdo.cpp:7: canopen/301 may not include canopen/io/clock.hpp (layer canopen/io is above canopen)

Usage: check_layers.py [ROOT]   (ROOT: the repository, default: two levels above this file)

A file belongs to the layer of the longest folder prefix in LAYERS. An include is resolved
relative to the including file first, then to ROOT (the project's include path); one that falls
in no layer (generated headers such as "oegw.h", system headers written with quotes) is not
checked. The CMake libraries follow the same table: each layer's library links the libraries of
the layers it may include (CMakeLists.txt in each folder).
"""
import os
import re
import sys

# folder -> layer, and the layers below each that it may include (its own layer always).
LAYERS = {
    "canopen": "canopen",            # oegw_canopen: CiA 301, 305, 306, sans I/O
    "canopen/io": "canopen/io",      # oegw_canopen_io: transports, clocks, event loop
    "profiles/cia401": "cia401",     # oegw_profiles
    "profiles/cia852": "cia852",     # oegw_profiles
    "subdevices": "drivers",         # oegw_drivers
    "subdevices/sim": "sim",         # oegw_sim
    "mapping": "mapping",            # oegw_mapping
    "gateway/publish": "publish",    # oegw_publish
    "gateway": "gateway",            # oegw_gateway: the daemon's library
    "cli": "cli",                    # oegw_cli: the commands' front-ends (register_<cmd>)
    "programs": "programs",          # oegw_programs and the executables
    "examples": "examples",          # the example subscribers: generated types only
    "tests": "tests",
}

# Rank: a layer includes only layers of a lower rank (and only those MAY lists).
RANK = {
    "canopen": 0,
    "canopen/io": 1,
    "cia401": 1,
    "cia852": 2,
    "drivers": 3,
    "sim": 3,
    "publish": 3,
    "mapping": 4,
    "gateway": 5,
    "cli": 6,
    "programs": 7,
    "examples": 7,
    "tests": 8,
}

MAY = {
    "canopen": set(),
    "canopen/io": {"canopen"},
    "cia401": {"canopen"},
    "cia852": {"canopen", "cia401"},
    "drivers": {"canopen", "cia401"},
    # Simulators follow the manufacturers' documents, not the drivers (see ALLOWED).
    "sim": {"canopen", "cia401", "cia852"},
    "publish": set(),
    "mapping": {"canopen", "cia401", "cia852", "drivers"},
    # The daemon runs no simulator.
    "gateway": {"canopen", "canopen/io", "cia401", "cia852", "drivers", "mapping", "publish"},
    # The front-ends parse the command line and call the daemon's library; they run no simulator either.
    "cli": {"canopen", "canopen/io", "cia401", "cia852", "drivers", "mapping", "publish", "gateway"},
    "programs": {"canopen", "canopen/io", "cia401", "cia852", "drivers", "sim", "mapping", "publish", "gateway", "cli"},
    "examples": set(),
    "tests": set(RANK) - {"tests"},
}

# Single includes across layers that the table does not declare, each with its reason:
# (including file or folder, included header).
ALLOWED = {
    # The bench programs' device spec ("family:node[:key=value,...]"), which make_simulator and
    # make_driver both take, and through which SimBench takes each device's signal list from the
    # family's driver (its sweep moves every signal the driver knows, by name).
    ("subdevices/sim/sim_bench.hpp", "subdevices/device_spec.hpp"),
    ("subdevices/sim/sim_registry.hpp", "subdevices/device_spec.hpp"),
    # The publishers publish the FE samples (header-only types of the gateway's FE model).
    ("gateway/publish", "gateway/fe_samples.hpp"),
    # The rule for publish.lcm.url (224.0.0.0/24, ttl=0) lives beside the LCM publisher; the
    # mapping file applies it at load time (gateway/publish/lcm_url.hpp: standard library only,
    # its own library oegw_lcm_url, no liblcm).
    ("mapping/sections/publish.cpp", "gateway/publish/lcm_url.hpp"),
    # The kernel's rule for an interface name lives beside the transport that opens the interface;
    # `oegw check` refuses the names the transport would (canopen/io/interface_name.hpp: header-only,
    # standard library only, no socket).
    ("mapping/deployment.cpp", "canopen/io/interface_name.hpp"),
    # ... and `oegw check` warns with it when LCM commands reach beyond the host.
    ("mapping/deployment.cpp", "gateway/publish/lcm_url.hpp"),
    # The exit codes of every command are one table (cli/exit_codes.hpp, constants only): the
    # daemon exits with them and the control socket's client commands return them.
    ("gateway", "cli/exit_codes.hpp"),
}

SOURCE_SUFFIXES = (".cpp", ".hpp", ".h", ".c", ".cpp.in", ".hpp.in", ".inl")
INCLUDE = re.compile(r'^\s*#\s*include\s*"([^"]+)"')


def layer_of(path):
    """The layer of a repository-relative path (forward slashes), or None."""
    best = None
    for folder in LAYERS:
        if path == folder or path.startswith(folder + "/"):
            if best is None or len(folder) > len(best):
                best = folder
    return LAYERS[best] if best is not None else None


def allowed(src, header):
    for who, what in ALLOWED:
        if header == what and (src == who or src.startswith(who + "/")):
            return True
    return False


def sources(root):
    for top, dirs, files in os.walk(root):
        rel_top = os.path.relpath(top, root)
        # Build trees, hidden folders (.git) and anything not ours.
        dirs[:] = sorted(d for d in dirs if not d.startswith(".") and not d.startswith("build"))
        if rel_top == ".":
            dirs[:] = [d for d in dirs if d in {p.split("/")[0] for p in LAYERS}]
        for f in sorted(files):
            if f.endswith(SOURCE_SUFFIXES):
                yield os.path.normpath(os.path.join(rel_top, f)).replace(os.sep, "/")


def resolve(root, src, name):
    """The repository-relative path `#include "name"` in `src` means."""
    beside = os.path.normpath(os.path.join(os.path.dirname(src), name)).replace(os.sep, "/")
    if not beside.startswith("../") and os.path.isfile(os.path.join(root, beside)):
        return beside
    return os.path.normpath(name).replace(os.sep, "/")


def reason(src_layer, inc_layer):
    if RANK[inc_layer] > RANK[src_layer]:
        return "layer %s is above %s" % (inc_layer, src_layer)
    if RANK[inc_layer] == RANK[src_layer]:
        return "layer %s is beside %s" % (inc_layer, src_layer)
    return "layer %s does not use %s" % (src_layer, inc_layer)


def check(root):
    problems = []
    for src in sources(root):
        src_layer = layer_of(src)
        if src_layer is None:
            continue
        with open(os.path.join(root, src), encoding="utf-8", errors="replace") as f:
            for number, line in enumerate(f, 1):
                m = INCLUDE.match(line)
                if not m:
                    continue
                header = resolve(root, src, m.group(1))
                inc_layer = layer_of(header)
                if inc_layer is None or inc_layer == src_layer or inc_layer in MAY[src_layer]:
                    continue
                if allowed(src, header):
                    continue
                folder = os.path.dirname(src) or "."
                problems.append("%s:%d: %s may not include %s (%s)" % (src, number, folder, header,
                                                                       reason(src_layer, inc_layer)))
    return problems


def main(argv):
    root = argv[1] if len(argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
    root = os.path.abspath(root)
    problems = check(root)
    for p in problems:
        print(p)
    if problems:
        print("%d undeclared include%s across layers (the table: %s)" %
              (len(problems), "" if len(problems) == 1 else "s", os.path.relpath(__file__, root)
               if os.path.abspath(__file__).startswith(root) else __file__))
        return 1
    print("layers: every include is declared")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
