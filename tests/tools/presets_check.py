#!/usr/bin/env python3
"""CMakePresets.json says what CONTRIBUTING.md "Presets" says it does, as cmake reads it.

  presets_check.py SOURCE_DIR BINARY_DIR

cmake --list-presets=all must accept the file (schema, cmake 3.25). The test presets must
select what their names promise, judged on the test list of this build tree (ctest --show-only
with the preset's filter): `dev` is tiers 1 and 2 (only unit and integration tests, never a VM
test, every one of them), `fast` everything but the VM tier and the Debian root, `ci` every test.
The filters are applied by ctest itself when BINARY_DIR is the presets' build/ tree; in another
tree they are applied here with ctest -L/-LE, the presets' own expressions.
Exit 0 when all hold, 1 naming the first that does not.
"""
import json
import os
import re
import subprocess
import sys


def fail(msg):
    print(f"presets_check: {msg}")
    sys.exit(1)


def tests(binary, *args):
    p = subprocess.run(["ctest", "--test-dir", binary, "--show-only=json-v1", *args],
                       capture_output=True, text=True)
    if p.returncode != 0:
        fail(f"ctest {' '.join(args)}: {p.stderr.strip()}")
    out = {}
    for t in json.loads(p.stdout).get("tests", []):
        labels = set()
        for prop in t.get("properties", []):
            if prop.get("name") == "LABELS":
                labels = set(prop.get("value", []))
        out[t["name"]] = labels
    return out


def main():
    src, binary = sys.argv[1], sys.argv[2]
    p = subprocess.run(["cmake", "--list-presets=all"], cwd=src, capture_output=True, text=True)
    if p.returncode != 0:
        fail(f"cmake --list-presets=all refuses CMakePresets.json: {p.stderr.strip()}")
    with open(os.path.join(src, "CMakePresets.json")) as f:
        presets = json.load(f)
    test_presets = {t["name"]: t for t in presets["testPresets"]}
    for name in ("dev", "fast", "ci"):
        if name not in test_presets:
            fail(f"no test preset '{name}' (CONTRIBUTING.md names it)")
        if name not in p.stdout:
            fail(f"cmake --list-presets does not list '{name}'")

    every = tests(binary)
    if not every:
        fail(f"{binary} has no tests: configure it with OEGW_BUILD_TESTS=ON")
    same_tree = os.path.realpath(binary) == os.path.realpath(os.path.join(src, "build"))
    for name, t in test_presets.items():
        filt = t.get("filter", {})
        inc = filt.get("include", {}).get("label")
        exc = filt.get("exclude", {}).get("label")
        if same_tree:
            p = subprocess.run(["ctest", "--preset", name, "--show-only=json-v1"], cwd=src,
                               capture_output=True, text=True)
            if p.returncode != 0:
                fail(f"ctest --preset {name}: {p.stderr.strip()}")
            chosen = {x["name"] for x in json.loads(p.stdout).get("tests", [])}
        else:
            args = (["-L", inc] if inc else []) + (["-LE", exc] if exc else [])
            chosen = set(tests(binary, *args))
        want = {n for n, labels in every.items()
                if (inc is None or any(re.search(inc, lb) for lb in labels))
                and not (exc and any(re.search(exc, lb) for lb in labels))}
        if chosen != want:
            fail(f"test preset '{name}' selects {len(chosen)} tests, its filter {len(want)}")
        if name == "dev":
            tier = lambda n: any(re.match(r"(unit|integration)\b", lb) for lb in every[n])  # noqa: E731
            bad = [n for n in chosen if not tier(n) or "vm" in every[n]]
            if bad:
                fail(f"test preset 'dev' runs {bad[0]}, which is neither unit nor integration")
            missing = [n for n in every if tier(n) and "vm" not in every[n] and n not in chosen]
            if missing:
                fail(f"test preset 'dev' leaves out {missing[0]} (labelled unit or integration)")
        if name == "fast":
            bad = [n for n in chosen if every[n] & {"vm", "deploy"}]
            if bad:
                fail(f"test preset 'fast' runs {bad[0]} (label vm or deploy)")
        if name == "ci" and chosen != set(every):
            fail(f"test preset 'ci' runs {len(chosen)} of {len(every)} tests")
        print(f"test preset '{name}': {len(chosen)} of {len(every)} tests")
    print("presets_check: CMakePresets.json is as CONTRIBUTING.md says")


if __name__ == "__main__":
    main()
