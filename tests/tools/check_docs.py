#!/usr/bin/env python3
"""Every link into the documentation resolves. MkDocs 1.4 (`mkdocs build --strict`, CTest
docs_site) reports a link to a page that is not there, but not a link to a heading that is not
there; a page split or a heading renamed would leave `page.md#anchor` links and the source
tree's citations pointing at nothing. This check fails on each of them:

* every Markdown link `[text](target)` in docs/, README.md and the other Markdown files (outside
  code spans and code blocks) whose target is a relative path: the file exists; for a `.md` target with `#anchor`
  (or a bare `#anchor`: the same page) the page has a heading with that anchor; a link from a
  page of docs/ stays inside docs/ (MkDocs builds only that folder, and --strict refuses a link
  out of it);
* every citation `docs/<path>.md` or `docs/<path>.md#<anchor>` in the other files of the
  repository (source comments in C++, Python, shell, CMake, YAML, …): the page exists and, with
  an anchor, has that heading.

An anchor is MkDocs' (Python-Markdown toc's default slugify) of the heading's text as rendered
(inline code, emphasis and links reduced to their text): Unicode folded to ASCII (NFKD, what has
no ASCII form dropped), every character other than word characters, white space and hyphens
dropped, lower case, each run of hyphens and white space one '-'. A second heading with the same
anchor on a page gets `_1`, a third `_2`.

Usage: check_docs.py [ROOT]   (ROOT: the repository, default: the working directory)

Exit 0 when everything resolves, 1 with one line per broken link or citation
(`file:line: ...`), 2 on a usage error. The files: what `git ls-files --cached --others
--exclude-standard` lists when ROOT is a git checkout, else every file below ROOT except the
build trees (build*/ at the top), .git and Python's caches; files with a NUL byte are skipped, and
so are this file and its test (check_docs_test.py), which name citations that must not resolve.
"""
import html
import os
import re
import sys

from tree_files import tree_files
import unicodedata

FENCE = re.compile(r"^ {0,3}(`{3,}|~{3,})")
HEADING = re.compile(r"^ {0,3}(#{1,6})[ \t]+(.*?)[ \t]*#*[ \t]*$")
CODE_SPAN = re.compile(r"(`+)(.+?)\1")
# [text](target "title"): the target up to white space or the closing parenthesis.
LINK = re.compile(r"!?\[((?:[^\[\]]|\[[^\[\]]*\])*)\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
CITATION = re.compile(r"(?<![\w.-])docs/((?:[\w.-]+/)*[\w.-]+\.md)(#[\w-]+)?")
SCHEME = re.compile(r"^[a-zA-Z][a-zA-Z0-9+.-]*:")
# This check and its test name citations that must not resolve.
SKIP = {os.path.abspath(__file__),
        os.path.join(os.path.dirname(os.path.abspath(__file__)), "check_docs_test.py")}


def slugify(text):
    """Python-Markdown toc's default slugify (MkDocs 1.4's anchors)."""
    text = unicodedata.normalize("NFKD", text).encode("ascii", "ignore").decode("ascii")
    text = re.sub(r"[^\w\s-]", "", text).strip().lower()
    return re.sub(r"[-\s]+", "-", text)


def heading_text(raw):
    """The text a heading renders to: code spans, links, emphasis and tags reduced to text."""
    parts = []
    pos = 0
    for m in CODE_SPAN.finditer(raw):
        parts.append(("md", raw[pos:m.start()]))
        parts.append(("code", m.group(2).strip()))
        pos = m.end()
    parts.append(("md", raw[pos:]))
    out = []
    for kind, text in parts:
        if kind == "md":
            text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", text)  # links and images
            text = re.sub(r"<[^>]+>", "", text)  # inline HTML
            text = re.sub(r"\\([\\`*_{}\[\]()#+\-.!])", r"\1", text)  # backslash escapes
            text = re.sub(r"(\*\*|__)(.+?)\1", r"\2", text)
            text = re.sub(r"(?<!\w)([*_])(.+?)\1(?!\w)", r"\2", text)
            text = html.unescape(text)
        out.append(text)
    return "".join(out)


def markdown_lines(text):
    """(line number, line) of the lines outside fenced code blocks, code spans blanked."""
    fence = None
    for number, line in enumerate(text.splitlines(), 1):
        m = FENCE.match(line)
        if fence:
            if m and m.group(1)[0] == fence[0] and len(m.group(1)) >= len(fence):
                fence = None
            continue
        if m:
            fence = m.group(1)
            continue
        if line.startswith("    ") or line.startswith("\t"):
            # An indented code block (a blank line before it); lists indent with two or fewer
            # spaces in this project's Markdown, so four mean code.
            continue
        yield number, line


def anchors_of(text):
    anchors = set()
    seen = {}
    for _, line in markdown_lines(text):
        m = HEADING.match(line)
        if not m:
            continue
        slug = slugify(heading_text(m.group(2)))
        if slug in seen:
            seen[slug] += 1
            slug_n = "%s_%d" % (slug, seen[slug])
            while slug_n in seen:
                seen[slug] += 1
                slug_n = "%s_%d" % (slug, seen[slug])
            seen[slug_n] = 0
            slug = slug_n
        else:
            seen[slug] = 0
        anchors.add(slug)
    return anchors


class Checker:
    def __init__(self, root):
        self.root = root
        self.anchor_cache = {}
        self.problems = []

    def read(self, rel):
        try:
            with open(os.path.join(self.root, rel), "rb") as f:
                data = f.read()
        except OSError:
            return None
        if b"\0" in data:
            return None
        return data.decode("utf-8", "replace")

    def anchors(self, rel):
        if rel not in self.anchor_cache:
            text = self.read(rel)
            self.anchor_cache[rel] = anchors_of(text) if text is not None else set()
        return self.anchor_cache[rel]

    def problem(self, rel, number, what):
        self.problems.append("%s:%d: %s" % (rel, number, what))

    def check_anchor(self, rel, number, shown, page, anchor):
        if anchor and anchor not in self.anchors(page):
            self.problem(rel, number, "%s: %s has no heading with the anchor #%s" %
                         (shown, page, anchor))

    def check_links(self, rel):
        """The Markdown links of one Markdown file."""
        text = self.read(rel)
        if text is None:
            return 0
        in_docs = rel.startswith("docs/")
        count = 0
        for number, line in markdown_lines(text):
            line = CODE_SPAN.sub(lambda m: " " * len(m.group(0)), line)
            for m in LINK.finditer(line):
                target = m.group(2)
                if SCHEME.match(target) or target.startswith("//"):
                    continue
                count += 1
                path, _, anchor = target.partition("#")
                if not path:
                    page = rel
                else:
                    page = os.path.normpath(os.path.join(os.path.dirname(rel), path))
                    page = page.replace(os.sep, "/")
                    if page.startswith("../") or page == "..":
                        self.problem(rel, number, "link %s leaves the repository" % target)
                        continue
                    if in_docs and not page.startswith("docs/"):
                        self.problem(rel, number, "link %s leaves docs/ (MkDocs builds only "
                                     "docs/; cite the file as text instead)" % target)
                        continue
                    full = os.path.join(self.root, page)
                    if not os.path.exists(full):
                        self.problem(rel, number, "link %s: %s does not exist" % (target, page))
                        continue
                    if os.path.isdir(full):
                        if anchor:
                            self.problem(rel, number, "link %s: an anchor on a folder" % target)
                        continue
                if anchor and page.endswith(".md"):
                    self.check_anchor(rel, number, "link " + target, page, anchor)
        return count

    def check_citations(self, rel):
        """The `docs/<page>.md#anchor` citations of one file outside docs/ (in a Markdown file,
        outside its links, which check_links checks)."""
        text = self.read(rel)
        if text is None:
            return 0
        count = 0
        for number, line in enumerate(text.splitlines(), 1):
            if rel.endswith(".md"):
                line = LINK.sub(" ", line)  # a Markdown link is checked as a link
            for m in CITATION.finditer(line):
                count += 1
                page = "docs/" + m.group(1)
                anchor = (m.group(2) or "#")[1:]
                if not os.path.isfile(os.path.join(self.root, page)):
                    self.problem(rel, number, "citation %s: %s does not exist" % (m.group(0), page))
                    continue
                self.check_anchor(rel, number, "citation " + m.group(0), page, anchor)
        return count


def main(argv):
    if len(argv) > 2 or (len(argv) == 2 and argv[1].startswith("-")):
        print(__doc__, file=sys.stderr)
        return 2
    root = os.path.abspath(argv[1] if len(argv) == 2 else os.getcwd())
    if not os.path.isdir(os.path.join(root, "docs")):
        print("check_docs: %s has no docs/ folder" % root, file=sys.stderr)
        return 2
    files = tree_files(root)
    checker = Checker(root)
    links = citations = 0
    for rel in files:
        if rel.endswith(".md"):
            links += checker.check_links(rel)
        if not rel.startswith("docs/") and os.path.abspath(os.path.join(root, rel)) not in SKIP:
            citations += checker.check_citations(rel)
    for line in checker.problems:
        print(line)
    sys.stdout.flush()
    if checker.problems:
        print("%d broken link(s) or citation(s)" % len(checker.problems), file=sys.stderr)
        return 1
    print("%d links in the Markdown and %d docs/ citations in %d files resolve" %
          (links, citations, len(files)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
