#!/usr/bin/env python3
"""The layer check: every `#include "..."` of the repository's sources against the table of which
layer may include which, and every namespace a source opens against its folder's namespace.
Exit 0 when both hold, 1 with one line per problem:

    canopen/301/pdo.cpp:7: canopen/301 may not include canopen/io/clock.hpp (layer canopen/io is above canopen)
    canopen/io/clock.hpp:9: namespace oegw::canopen is not in canopen/io's namespace oegw::canopen::io

Usage: check_layers.py [ROOT]   (ROOT: the repository, default: two levels above this file)

A file belongs to the layer of the longest folder prefix in LAYERS. An include is resolved
relative to the including file first, then to ROOT (the project's include path); one that falls
in no layer (generated headers such as "oegw.h", system headers written with quotes) is not
checked. The CMake libraries follow the same table: each layer's library links the libraries of
the layers it may include (CMakeLists.txt in each folder).

A file's namespace is that of the longest folder prefix in NAMESPACES. Each named namespace a file
opens outside its folder's namespace must be that namespace, below it, or on the way to it
(`namespace oegw {` then `namespace canopen {`); inside it, helper namespaces are free.
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
    "publish": "publish",            # oegw_publish, oegw_lcm_url
    "gateway": "gateway",            # oegw_gateway: the daemon's library
    "rig": "rig",                    # oegw_rig: the simulated cab
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
    "rig": 6,
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
    # The simulated cab: the daemon's library between simulators and a host, on virtual buses.
    "rig": {"canopen", "canopen/io", "cia401", "cia852", "drivers", "sim", "mapping", "gateway"},
    # The front-ends parse the command line and call the daemon's library; they run no simulator either.
    "cli": {"canopen", "canopen/io", "cia401", "cia852", "drivers", "mapping", "publish", "gateway"},
    "programs": {"canopen", "canopen/io", "cia401", "cia852", "drivers", "sim", "mapping", "publish", "gateway",
                 "rig", "cli"},
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
    # The publishers publish the FE samples: header-only types of the gateway's FE model and the
    # Publisher interface the gateway drives (namespace oegw::gateway, used by the FE model, the
    # command arbiter and the daemon's commands alike; it stays with them).
    ("publish", "gateway/fe_samples.hpp"),
    # The rule for publish.lcm.url (224.0.0.0/24, ttl=0) lives beside the LCM publisher; the
    # mapping file applies it at load time (publish/lcm_url.hpp: standard library only,
    # its own library oegw_lcm_url, no liblcm).
    ("mapping/sections/publish.cpp", "publish/lcm_url.hpp"),
    # The kernel's rule for an interface name lives beside the transport that opens the interface;
    # `oegw check` refuses the names the transport would (canopen/io/interface_name.hpp: header-only,
    # standard library only, no socket).
    ("mapping/deployment.cpp", "canopen/io/interface_name.hpp"),
    # ... and looks up control.group as the control server does, reentrantly: a reload checks its
    # file in a thread beside the event loop (canopen/io/user_db.hpp: header-only, libc only).
    ("mapping/deployment.cpp", "canopen/io/user_db.hpp"),
    # ... and `oegw check` warns with it when LCM commands reach beyond the host.
    ("mapping/deployment.cpp", "publish/lcm_url.hpp"),
    # The exit codes of every command are one table (cli/exit_codes.hpp, constants only): the
    # daemon exits with them and the control socket's client commands return them.
    ("gateway", "cli/exit_codes.hpp"),
}

# folder -> the namespace its files declare (the longest prefix applies; tests and examples
# reopen the namespaces they test or use and are not checked).
NAMESPACES = {
    "canopen": "oegw::canopen",
    "canopen/io": "oegw::canopen::io",
    "profiles/cia401": "oegw::cia401",
    "profiles/cia852": "oegw::cia852",
    "subdevices": "oegw::subdevices",
    "subdevices/sim": "oegw::subdevices::sim",
    "mapping": "oegw::mapping",
    "publish": "oegw::publish",
    "gateway": "oegw::gateway",
    "gateway/record": "oegw::gateway::record",
    "gateway/control": "oegw::gateway::control",
    "rig": "oegw::rig",
    "programs": "oegw::programs",
    "cli": "oegw::cli",
}

# Other libraries' namespaces, where a file may forward-declare their types or specialize their
# templates (spdlog::logger in gateway/daemon_log.hpp, std::hash, fmt::formatter).
FOREIGN = {"std", "fmt", "spdlog", "nlohmann"}

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
            dirs[:] = [d for d in dirs if d in {p.split("/")[0] for p in list(LAYERS) + list(NAMESPACES)}]
        for f in sorted(files):
            if f.endswith(SOURCE_SUFFIXES):
                yield os.path.normpath(os.path.join(rel_top, f)).replace(os.sep, "/")


def resolve(root, src, name):
    """The repository-relative path `#include "name"` in `src` means."""
    beside = os.path.normpath(os.path.join(os.path.dirname(src), name)).replace(os.sep, "/")
    if not beside.startswith("../") and os.path.isfile(os.path.join(root, beside)):
        return beside
    return os.path.normpath(name).replace(os.sep, "/")


def longest_prefix(path, table):
    """The longest folder of `table` that holds `path`, or None."""
    best = None
    for folder in table:
        if path == folder or path.startswith(folder + "/"):
            if best is None or len(folder) > len(best):
                best = folder
    return best


# Comments, string and character literals (raw strings included): blanked before the namespaces
# and braces are read, so that a brace or the word namespace in them counts for nothing.
LEXEME = re.compile(r'//[^\n]*|/\*.*?\*/|R"([^(\s]*)\(.*?\)\1"|"(?:[^"\\\n]|\\.)*"|\'(?:[^\'\\\n]|\\.)*\'',
                    re.S)
NAMESPACE = re.compile(r"\b(?:inline\s+)?namespace\s+([A-Za-z_][\w:]*)?\s*\{|[{}]")


def blank(text):
    """`text` with comments and literals replaced by spaces (newlines kept: line numbers hold)."""
    return LEXEME.sub(lambda m: re.sub(r"[^\n]", " ", m.group(0)), text)


def at_or_below(name, top):
    return name == top or name.startswith(top + "::")


def namespace_problems(path, text, expected):
    """One (line, message) per named namespace `text` opens outside `expected`."""
    problems = []
    stack = []  # per open brace: the namespace outside it and the line that opened that one
    current, opened = "", 0
    # A namespace on the way to `expected` (oegw, for oegw::canopen::io) holds only namespaces:
    # the line that opened it is reported (once) if anything else is declared directly in it.
    reported = set()
    code = blank(text)
    code = re.sub(r"(?m)^[ \t]*#.*$", lambda m: " " * len(m.group(0)), code)  # preprocessor lines
    last = 0

    def line_of(offset):
        return code.count("\n", 0, offset) + 1

    def report(line, full):
        if line not in reported:
            reported.add(line)
            problems.append((line, "namespace %s is not in %s's namespace %s" % (full, path, expected)))

    for m in NAMESPACE.finditer(code):
        between = code[last:m.start()]
        last = m.end()
        if current and expected.startswith(current + "::") and between.strip():
            report(opened, current)
        token = m.group(0)
        if token == "}":
            if stack:
                current, opened = stack.pop()
            continue
        if token == "{":
            stack.append((current, opened))
            continue
        stack.append((current, opened))
        name = m.group(1)
        if name is None:  # anonymous: internal to the file, wherever it is
            continue
        full = current + "::" + name if current else name
        if not at_or_below(current, expected) and full.split("::")[0] not in FOREIGN:
            # Outside the folder's namespace: this one must be in it or lead to it.
            if not at_or_below(full, expected) and not expected.startswith(full + "::"):
                report(line_of(m.start()), full)
        current, opened = full, line_of(m.start())
    return problems


def check_namespaces(root):
    """Lines `file:line: message`."""
    problems = []
    for src in sources(root):
        folder = longest_prefix(src, NAMESPACES)
        if folder is None:
            continue
        with open(os.path.join(root, src), encoding="utf-8", errors="replace") as f:
            text = f.read()
        for line, message in namespace_problems(folder, text, NAMESPACES[folder]):
            problems.append("%s:%d: %s" % (src, line, message))
    return problems


def check_unit_folders(root):
    """Lines `file: message`: tests/unit's sub-folders mirror the source, so that a service's test
    is found where the service is (tests/unit/canopen/301/ holds the tests of canopen/301/)."""
    problems = []
    unit = os.path.join(root, "tests", "unit")
    for folder, _, names in sorted(os.walk(unit)):
        rel = os.path.relpath(folder, unit).replace(os.sep, "/")
        for name in sorted(n for n in names if n.endswith("_test.cpp")):
            path = "tests/unit/%s" % name if rel == "." else "tests/unit/%s/%s" % (rel, name)
            if rel == ".":
                problems.append("%s: a unit test sits in the folder of what it tests "
                                "(tests/unit/<source folder>/), not in tests/unit itself" % path)
            elif not os.path.isdir(os.path.join(root, rel)):
                problems.append("%s: tests/unit/%s mirrors no source folder (there is no %s/)" % (path, rel, rel))
    return problems


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
    table = os.path.relpath(__file__, root) if os.path.abspath(__file__).startswith(root) else __file__
    problems = check(root)
    ns_problems = check_namespaces(root)
    unit_problems = check_unit_folders(root)
    for p in problems + ns_problems + unit_problems:
        print(p)
    if problems:
        print("%d undeclared include%s across layers (the table: %s)" %
              (len(problems), "" if len(problems) == 1 else "s", table))
    if ns_problems:
        print("%d namespace%s outside the folder's (the table: %s NAMESPACES)" %
              (len(ns_problems), "" if len(ns_problems) == 1 else "s", table))
    if unit_problems:
        print("%d unit test%s outside the folder mirroring what %s test%s" %
              (len(unit_problems), "" if len(unit_problems) == 1 else "s",
               "it" if len(unit_problems) == 1 else "they", "s" if len(unit_problems) == 1 else ""))
    if problems or ns_problems or unit_problems:
        return 1
    print("layers: every include is declared, every namespace is its folder's, "
          "every unit test in the folder mirroring its source")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
