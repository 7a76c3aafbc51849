#!/usr/bin/env python3
"""The documentation check can fail: check_docs.py on small trees with a broken link or citation
must exit 1 and name the file, the line and what does not resolve; on a clean tree (anchors as
MkDocs makes them, a repeated heading's `_1`) it exits 0.

Usage: check_docs_test.py PATH/TO/check_docs.py
"""
import os
import shutil
import subprocess
import sys
import tempfile


def tree(files):
    root = tempfile.mkdtemp(prefix="oegw-docs-")
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
    "README.md": "# x\n\nSee [the route](docs/guides/install.md#lcm-route).\n",
    "docs/index.md": "# Home\n\n[Install](guides/install.md), [again](guides/install.md#installing_1).\n",
    "docs/guides/install.md": (
        "# Install and run\n\n## Installing\n\n## LCM route\n\n"
        "```sh\n## not a heading\n```\n\n"
        "## Installing\n\n"                       # a second one: #installing_1
        "## Asking the running gateway: `oegw status`\n\n"
        "## Commissioning: `oegw ctl`\n\n"
        "## `upstream` — the gateway on the host's bus (required)\n\n"
        "## Clause-9 layout decisions (profiles/cia852/fe_table.hpp)\n\n"
        "See [below](#lcm-route) and [the code](`x`).\n"),
    "docs/reference/limits.md": (
        "# Limits\n\n[a](../guides/install.md#asking-the-running-gateway-oegw-status) "
        "[b](../guides/install.md#commissioning-oegw-ctl) "
        "[c](../guides/install.md#upstream-the-gateway-on-the-hosts-bus-required) "
        "[d](../guides/install.md#clause-9-layout-decisions-profilescia852fe_tablehpp) "
        "[e](https://example.org/x.md#nothing) `[f](nowhere.md)`\n"),
    "gateway/x.cpp": "// The route (docs/guides/install.md#lcm-route); the page (docs/reference/limits.md).\n",
    "scripts/y.sh": "# docs/guides/install.md#installing_1\n",
}

CASES = [
    # (file, text, expected in the report)
    ("docs/index.md", "# Home\n\n[x](guides/install.md#lcm-routes)\n",
     "docs/index.md:3: link guides/install.md#lcm-routes: docs/guides/install.md has no heading "
     "with the anchor #lcm-routes"),
    ("docs/index.md", "# Home\n\n\n[x](#home) [y](#away)\n",
     "docs/index.md:4: link #away: docs/index.md has no heading with the anchor #away"),
    ("README.md", "# x\n\n[x](docs/guides/missing.md)\n",
     "README.md:3: link docs/guides/missing.md: docs/guides/missing.md does not exist"),
    ("docs/index.md", "# Home\n\n[x](../gateway/x.cpp)\n",
     "docs/index.md:3: link ../gateway/x.cpp leaves docs/"),
    ("gateway/x.cpp", "int x;\n// see docs/guides/install.md#lcm_route\n",
     "gateway/x.cpp:2: citation docs/guides/install.md#lcm_route: docs/guides/install.md has no "
     "heading with the anchor #lcm_route"),
    ("scripts/y.sh", "# docs/guides/install.md#installing_2\n",
     "scripts/y.sh:1: citation docs/guides/install.md#installing_2"),
    ("tests/z.py", "# docs/design/fault-policy.md\n",
     "tests/z.py:1: citation docs/design/fault-policy.md: docs/design/fault-policy.md does not exist"),
]


def main(argv):
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    checker = argv[1]
    failures = 0
    code, out = run(checker, tree(CLEAN))
    if code != 0:
        print("FAIL: the clean tree is refused (exit %d):\n%s" % (code, out))
        failures += 1
    else:
        print("ok: clean tree accepted: %s" % out.strip())
    for path, text, expected in CASES:
        files = dict(CLEAN)
        files[path] = text
        code, out = run(checker, tree(files))
        if code != 1 or expected not in out:
            print("FAIL: %s with %r: exit %d, expected 1 and %r in:\n%s" % (path, text, code, expected, out))
            failures += 1
        else:
            print("ok: %s" % expected)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
