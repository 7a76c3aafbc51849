#!/usr/bin/env python3
"""No file of the repository cites an issue number. The project has no tracker its reader can
follow: a comment, a document or a test name states the behaviour and its reason (citing the
standard's clause or the device document where there is one), and the history of a change goes
in its commit message (CONTRIBUTING.md). Exit 0 when no file does, 1 with one line per citation:

    gateway/example.hpp:12: // what the citation's line says

Usage: check_no_issue_refs.py [ROOT]   (ROOT: the repository, default: the working directory)

The files: what `git ls-files --cached --others --exclude-standard` lists when ROOT is a git
checkout (tracked files and new ones not ignored), else every file below ROOT except the build
trees (build*/ at the top), .git and Python's caches. Files with a NUL byte (binary) are skipped,
and so is this file, which has to name the pattern. A citation is the word "issue" or "issues"
followed by a number (an optional space and '#' between them), in any case, also when a comment
wraps between the word and the number.
"""
import os
import re
import sys

from tree_files import tree_files

CITATION = re.compile(r"\bissues? ?#?[0-9]+", re.IGNORECASE)
# A line that ends in the word, and the next line's text (after its comment leader) that starts
# with the number: a citation a comment wrapped.
WORD_AT_END = re.compile(r"\bissues?\s*#?\s*$", re.IGNORECASE)
NUMBER_AT_START = re.compile(r"^\s*(?://+|/\*+|\*+|#+|--|;+|>+)?\s*#?[0-9]")

SELF = os.path.abspath(__file__)


def citations(root, rel):
    path = os.path.join(root, rel)
    if not os.path.isfile(path) or os.path.abspath(path) == SELF:
        return []
    with open(path, "rb") as f:
        data = f.read()
    if b"\0" in data:
        return []
    lines = data.decode("utf-8", "replace").splitlines()
    found = []
    for i, line in enumerate(lines):
        if CITATION.search(line):
            found.append("%s:%d: %s" % (rel, i + 1, line.strip()))
        elif i + 1 < len(lines) and WORD_AT_END.search(line) and \
                NUMBER_AT_START.match(lines[i + 1]):
            found.append("%s:%d: %s / %s" % (rel, i + 1, line.strip(), lines[i + 1].strip()))
    return found


def main(argv):
    if len(argv) > 2:
        print(__doc__, file=sys.stderr)
        return 2
    root = os.path.abspath(argv[1] if len(argv) == 2 else os.getcwd())
    files = tree_files(root)
    found = []
    for rel in files:
        found += citations(root, rel)
    for line in found:
        print(line)
    if found:
        print("%d citation(s) of an issue number: state the behaviour and its reason instead; the "
              "history goes in the commit message (CONTRIBUTING.md)" % len(found), file=sys.stderr)
        return 1
    print("no citation of an issue number in %d files" % len(files))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
