#!/usr/bin/env python3
"""The tree's shell and Python lint: shellcheck over scripts/*.sh and tests/**/*.sh (with the
repository's .shellcheckrc: each justified exception is written there or on the line above its
finding), pyflakes3 over every Python file. Exits 1 on any finding, naming each as
file:line:column; 2 when a tool is missing (scripts/install-deps.sh --tests installs both).

    lint.py SOURCE_DIR [shell|python ...]
"""
import os
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tree_files import tree_files  # noqa: E402


def shell_files(files):
    return [f for f in files if f.endswith(".sh") and (f.startswith("scripts/") and f.count("/") == 1
                                                       or f.startswith("tests/"))]


def python_files(files):
    return [f for f in files if f.endswith(".py")]


def run(tool, args, files, root):
    exe = shutil.which(tool)
    if exe is None:
        print(f"lint: {tool} is not installed (scripts/install-deps.sh --tests installs it)")
        sys.exit(2)
    if not files:
        print(f"lint: no files for {tool}")
        return 1
    p = subprocess.run([exe, *args, *files], cwd=root, capture_output=True, text=True)
    out = (p.stdout + p.stderr).strip()
    if p.returncode != 0 or out:
        print(out)
        print(f"lint: {tool} found the above in {len(files)} files")
        return 1
    print(f"lint: {tool}: {len(files)} files, no finding")
    return 0


def main(argv):
    if len(argv) < 2:
        print(__doc__.strip())
        return 64
    root = argv[1]
    kinds = argv[2:] or ["shell", "python"]
    files = tree_files(root)
    bad = 0
    for kind in kinds:
        if kind == "shell":
            bad |= run("shellcheck", ["-f", "gcc"], shell_files(files), root)
        elif kind == "python":
            bad |= run("pyflakes3", [], python_files(files), root)
        else:
            print(f"lint: unknown kind '{kind}'; expected shell or python")
            return 64
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
