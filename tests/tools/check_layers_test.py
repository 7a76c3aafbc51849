#!/usr/bin/env python3
"""The layer check can fail: check_layers.py on small file trees with a bad include must exit
non-zero and name the file, the line, the header and the layers; on a clean tree it exits 0.

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
    "canopen/types.hpp": "#pragma once\n",
    "canopen/io/clock.hpp": '#pragma once\n#include "canopen/types.hpp"\n',
    "canopen/301/pdo.cpp": '#include "canopen/types.hpp"\n#include <vector>\n#include "oegw.h"\n',
    "subdevices/driver.hpp": '#pragma once\n#include "canopen/types.hpp"\n',
    "subdevices/device_spec.hpp": '#pragma once\n#include "subdevices/driver.hpp"\n',
    "subdevices/sim/sim_bench.hpp": '#pragma once\n#include "subdevices/device_spec.hpp"\n',
    "tests/unit/x_test.cpp": '#include "subdevices/sim/sim_bench.hpp"\n#include "support.hpp"\n',
    "tests/unit/support.hpp": "#pragma once\n",
}

CASES = [
    # (file, text, expected line of the report)
    ("canopen/301/pdo.cpp", '#include "canopen/types.hpp"\n\n#include "canopen/io/clock.hpp"\n',
     "canopen/301/pdo.cpp:3: canopen/301 may not include canopen/io/clock.hpp (layer canopen/io is above canopen)"),
    ("subdevices/sim/mcb402_sim.hpp", '#pragma once\n#include "subdevices/driver.hpp"\n',
     "subdevices/sim/mcb402_sim.hpp:2: subdevices/sim may not include subdevices/driver.hpp "
     "(layer drivers is beside sim)"),
    ("canopen/node.hpp", '#pragma once\n#  include "tests/unit/support.hpp"\n',
     "canopen/node.hpp:2: canopen may not include tests/unit/support.hpp (layer tests is above canopen)"),
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
