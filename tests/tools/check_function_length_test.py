#!/usr/bin/env python3
"""check_function_length.py on temporary trees: a new long function fails, a known one may not
grow, a known one now short or gone must leave KNOWN, tests/ is not checked, a short tree passes.

    check_function_length_test.py CHECK_FUNCTION_LENGTH_PY
"""
import importlib.util
import os
import shutil
import sys
import tempfile


def load(path):
    spec = importlib.util.spec_from_file_location("check_function_length", path)
    mod = importlib.util.module_from_spec(spec)
    sys.path.insert(0, os.path.dirname(os.path.abspath(path)))
    spec.loader.exec_module(mod)
    return mod


def function(name, body_lines):
    return f"int {name}() {{\n" + "".join(f"  int v{i} = {i};\n" for i in range(body_lines)) + "  return 0;\n}\n"


MADE = []


def tree(files):
    d = tempfile.mkdtemp()
    MADE.append(d)
    for rel, text in files.items():
        p = os.path.join(d, rel)
        os.makedirs(os.path.dirname(p), exist_ok=True)
        with open(p, "w") as f:
            f.write(text)
    return d


def main(argv):
    mod = load(argv[1])
    failures = []

    def expect(what, findings, *wanted):
        if not wanted and findings:
            failures.append(f"{what}: expected no finding, got {findings}")
        for w in wanted:
            if not any(w in f for f in findings):
                failures.append(f"{what}: expected a finding with '{w}', got {findings}")

    # 118 body lines + signature + return + brace = 121 lines; 117 -> 120.
    long_fn, limit_fn = function("long_one", 118), function("at_limit", 117)
    expect("a function of exactly 120 lines passes",
           mod.check(tree({"lib/a.cpp": limit_fn}), {}))
    expect("a new function of 121 lines fails",
           mod.check(tree({"lib/a.cpp": long_fn}), {}), "lib/a.cpp: long_one is 121 lines, over 120")
    expect("a known one at its length passes",
           mod.check(tree({"lib/a.cpp": long_fn}), {"lib/a.cpp": {"long_one": 121}}))
    expect("a known one that grew fails",
           mod.check(tree({"lib/a.cpp": function("long_one", 130)}), {"lib/a.cpp": {"long_one": 121}}),
           "long_one grew to 133 lines (at most 121")
    expect("a known one now short must leave KNOWN",
           mod.check(tree({"lib/a.cpp": limit_fn.replace("at_limit", "long_one")}),
                     {"lib/a.cpp": {"long_one": 121}}),
           "long_one is 120 lines now, at most 120: remove it from KNOWN")
    expect("a known one gone (moved) must leave KNOWN",
           mod.check(tree({"lib/b.cpp": long_fn}), {"lib/a.cpp": {"long_one": 121}}),
           "lib/a.cpp: long_one (in KNOWN, 121 lines) is not there any more",
           "lib/b.cpp: long_one is 121 lines, over 120")
    expect("tests/ is not checked",
           mod.check(tree({"tests/a_test.cpp": long_fn}), {}))
    cls = "struct S {\n  int m();\n};\n" + long_fn.replace("int long_one()", "int S::m()")
    expect("a member is named with its class",
           mod.check(tree({"lib/s.cpp": cls}), {}), "lib/s.cpp: S::m is 121 lines")
    lam = "void outer() {\n  auto step = [&]() {\n" + "".join(f"    f({i});\n" for i in range(120)) + "  };\n}\n"
    expect("a named lambda counts as enclosing::name",
           mod.check(tree({"lib/l.cpp": lam}), {}), "outer::step is 122 lines")

    for d in MADE:
        shutil.rmtree(d)
    for f in failures:
        print("FAIL:", f)
    print("check_function_length_test:", "FAILED" if failures else "all cases pass")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
