#!/usr/bin/env python3
"""Fails on a C++ function longer than LIMIT lines outside tests/ (a long function is hard to
review and to test piece by piece).

    check_function_length.py SOURCE_DIR

Functions are found by universal-ctags (`ctags --languages=C++ --kinds-C++=f --fields=+ne`: the
first and last line of each definition; a lambda bound to a name counts as a function of its own,
named enclosing::name). KNOWN lists today's offenders, each with its length then: it may only
shrink. The check fails, saying which and what to do, when
  * a function not in KNOWN is longer than LIMIT;
  * a function in KNOWN grew beyond its recorded length;
  * a function in KNOWN is now at most LIMIT lines, or is gone (moved, renamed, split): its
    entry must be removed (or moved with it), so that the list only ever gets shorter.
Exit 0 clean, 1 on any finding, 2 when ctags is missing (scripts/install-deps.sh --tests).
"""
import os
import re
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tree_files import tree_files  # noqa: E402

LIMIT = 120
SUFFIXES = (".cpp", ".hpp", ".cc", ".h", ".c")

# {path: {function: lines}}: the functions over LIMIT lines when this check came, each at most
# the length it had then. Remove an entry when its function is split to LIMIT lines or fewer.
KNOWN = {
}

LAMBDA_NAME = re.compile(r"(\w+)\s*=\s*\[")


def last_named(scope):
    parts = [p for p in scope.split("::") if p and not p.startswith("__anon")]
    return parts[-1] if parts else ""


def function_name(name, pattern, fields):
    """Class::name, or enclosing::variable for a lambda (ctags names it __anon...)."""
    if name.startswith("__anon"):
        m = LAMBDA_NAME.search(pattern)
        var = m.group(1) if m else "<lambda>"
        outer = last_named(fields.get("function", ""))
        return f"{outer}::{var}" if outer else var
    for kind in ("class", "struct"):
        if kind in fields:
            return f"{last_named(fields[kind])}::{name}"
    return name


def measure(root, files):
    """{path: {function: longest length}} of every function in files (paths relative to root)."""
    exe = shutil.which("ctags")
    if exe is None:
        print("check_function_length: ctags is not installed (universal-ctags; "
              "scripts/install-deps.sh --tests installs it)")
        sys.exit(2)
    out = {}
    if not files:
        return out
    p = subprocess.run([exe, "--languages=C++", "--language-force=C++", "--kinds-C++=f",
                        "--fields=+ne", "-f", "-", "-L", "-"], cwd=root, input="\n".join(files),
                       capture_output=True, text=True)
    if p.returncode != 0:
        print(f"check_function_length: ctags failed: {p.stderr.strip()}")
        sys.exit(2)
    for line in p.stdout.splitlines():
        cols = line.split("\t")
        if len(cols) < 4 or line.startswith("!_"):
            continue
        name, path = cols[0], cols[1]
        pattern = cols[2]
        fields = {}
        for c in cols[3:]:
            k, sep, v = c.partition(":")
            if sep:
                fields[k] = v
        if "line" not in fields or "end" not in fields:
            continue
        length = int(fields["end"]) - int(fields["line"]) + 1
        fn = function_name(name, pattern, fields)
        per_file = out.setdefault(path, {})
        per_file[fn] = max(length, per_file.get(fn, 0))
    return out


def check(root, known, limit=LIMIT):
    """The findings, one line each (empty when clean)."""
    files = [f for f in tree_files(root)
             if f.endswith(SUFFIXES) and not f.startswith("tests/")]
    lengths = measure(root, files)
    findings = []
    for path in sorted(lengths):
        for fn, n in sorted(lengths[path].items()):
            if n <= limit:
                continue
            was = known.get(path, {}).get(fn)
            if was is None:
                findings.append(f"{path}: {fn} is {n} lines, over {limit}: split it")
            elif n > was:
                findings.append(f"{path}: {fn} grew to {n} lines (at most {was}, over {limit}): "
                                "it may only shrink")
    for path in sorted(known):
        for fn, was in sorted(known[path].items()):
            n = lengths.get(path, {}).get(fn)
            if n is None:
                findings.append(f"{path}: {fn} (in KNOWN, {was} lines) is not there any more: "
                                "remove its entry from KNOWN in tests/tools/check_function_length.py, "
                                "or move it with the function")
            elif n <= limit:
                findings.append(f"{path}: {fn} is {n} lines now, at most {limit}: remove it from "
                                "KNOWN in tests/tools/check_function_length.py")
    return findings


def main(argv):
    if len(argv) != 2:
        print(__doc__.strip())
        return 64
    findings = check(argv[1], KNOWN)
    for f in findings:
        print(f)
    if findings:
        print(f"check_function_length: {len(findings)} finding(s)")
        return 1
    print(f"check_function_length: no function over {LIMIT} lines outside tests/ but the "
          f"{sum(len(v) for v in KNOWN.values())} known")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
