#!/usr/bin/env python3
"""The layer check can fail: check_layers.py on small file trees with a bad include or a namespace
outside its folder's must exit non-zero and name the file, the line and the reason; on a clean
tree it exits 0.

Usage: check_layers_test.py PATH/TO/check_layers.py
"""
import os
import shutil
import subprocess
import sys
import tempfile


def tree(files):
    root = tempfile.mkdtemp(prefix="oegw-layers-")
    for path, text in files.items():
        full = os.path.join(root, path)
        os.makedirs(os.path.dirname(full), exist_ok=True)
        with open(full, "w") as f:
            f.write(text)
    return root


def run(checker, root):
    try:
        p = subprocess.run([sys.executable, checker, root], capture_output=True, text=True)
        return p.returncode, p.stdout + p.stderr
    finally:
        shutil.rmtree(root)


CLEAN = {
    "canopen/types.hpp": "#pragma once\nnamespace oegw::canopen {\nnamespace detail {}\n}\n",
    "canopen/io/clock.hpp": '#pragma once\n#include "canopen/types.hpp"\n'
                            "namespace oegw {\nnamespace canopen::io {\nstruct Clock {};\n}\n}\n",
    # Braces and the word namespace in comments and literals count for nothing; other libraries'
    # namespaces take forward declarations; anonymous namespaces are the file's own.
    "subdevices/sim/sim_bench.cpp": "// namespace oegw::gateway {\nnamespace spdlog { class logger; }\n"
                                    'namespace oegw::subdevices::sim {\nconst char* s = "namespace x { {";\n'
                                    "const char c = '{';\nnamespace {\nint n;\n}\n}  // namespace oegw::subdevices::sim\n"
                                    "namespace {\nint m;\n}\n",
    "canopen/301/pdo.cpp": '#include "canopen/types.hpp"\n#include <vector>\n#include "oegw.h"\n',
    "subdevices/driver.hpp": '#pragma once\n#include "canopen/types.hpp"\n',
    "subdevices/device_spec.hpp": '#pragma once\n#include "subdevices/driver.hpp"\n',
    "subdevices/sim/sim_bench.hpp": '#pragma once\n#include "subdevices/device_spec.hpp"\n'
                                    "namespace oegw {\nnamespace subdevices::sim {\nstruct SimBench {};\n}\n}\n",
    "tests/unit/subdevices/sim/x_test.cpp": '#include "subdevices/sim/sim_bench.hpp"\n#include "support.hpp"\n',
    "tests/unit/subdevices/sim/support.hpp": "#pragma once\n",
}

CASES = [
    # (file, text, expected line of the report)
    ("canopen/301/pdo.cpp", '#include "canopen/types.hpp"\n\n#include "canopen/io/clock.hpp"\n',
     "canopen/301/pdo.cpp:3: canopen/301 may not include canopen/io/clock.hpp (layer canopen/io is above canopen)"),
    ("subdevices/sim/mcb402_sim.hpp", '#pragma once\n#include "subdevices/driver.hpp"\n',
     "subdevices/sim/mcb402_sim.hpp:2: subdevices/sim may not include subdevices/driver.hpp "
     "(layer drivers is beside sim)"),
    ("canopen/node.hpp", '#pragma once\n#  include "tests/unit/subdevices/sim/support.hpp"\n',
     "canopen/node.hpp:2: canopen may not include tests/unit/subdevices/sim/support.hpp (layer tests is above canopen)"),
    # A unit test outside the folder that mirrors what it tests.
    ("tests/unit/y_test.cpp", "",
     "tests/unit/y_test.cpp: a unit test sits in the folder of what it tests (tests/unit/<source folder>/), "
     "not in tests/unit itself"),
    ("tests/unit/widgets/y_test.cpp", "",
     "tests/unit/widgets/y_test.cpp: tests/unit/widgets mirrors no source folder (there is no widgets/)"),
    # A namespace of another folder.
    ("subdevices/sim/sim_bench.hpp", '#pragma once\n\nnamespace oegw::subdevices {\nstruct SimBench {};\n}\n',
     "subdevices/sim/sim_bench.hpp:3: namespace oegw::subdevices is not in subdevices/sim's namespace "
     "oegw::subdevices::sim"),
    # ... reached step by step, declaring in the step.
    ("subdevices/sim/sim_bench.hpp", "namespace oegw {\nnamespace subdevices {\nstruct SimBench {};\n}\n}\n",
     "subdevices/sim/sim_bench.hpp:2: namespace oegw::subdevices is not in subdevices/sim's namespace "
     "oegw::subdevices::sim"),
    # ... or another layer's, after the right one closed.
    ("subdevices/driver.hpp", "namespace oegw::subdevices {\n}\nnamespace oegw::gateway {\nclass Gateway;\n}\n",
     "subdevices/driver.hpp:3: namespace oegw::gateway is not in subdevices's namespace oegw::subdevices"),
    # The programs compose the daemon's library but declare their own namespace.
    ("programs/demo.cpp", "namespace oegw::gateway {\nint demo();\n}\n",
     "programs/demo.cpp:1: namespace oegw::gateway is not in programs's namespace oegw::programs"),
]

def main(argv):
    checker = argv[1]
    failures = []
    rc, out = run(checker, tree(CLEAN))
    if rc != 0:
        failures.append("clean tree: exit %d, expected 0:\n%s" % (rc, out))
    for path, text, expected in CASES:
        files = dict(CLEAN)
        files[path] = text
        rc, out = run(checker, tree(files))
        if rc == 0:
            failures.append("%s: exit 0, expected a failure" % path)
        if expected not in out.splitlines():
            failures.append("%s: expected the line\n  %s\ngot:\n%s" % (path, expected, out))
    for f in failures:
        print(f)
    print("%d of %d cases failed" % (len(failures), len(CASES) + 1) if failures else "check_layers.py: all cases ok")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
