"""The files of a source tree that the tree checks read (check_docs.py, check_no_issue_refs.py).

tree_files(root): what git tracks below root plus the untracked files it does not ignore (so a
new file is checked before it is added), or, where root is no checkout or git is missing, every
file below root but the build trees and caches at the top, .git and Python's caches.
Paths relative to root, with "/", sorted.
"""
import os
import subprocess


def git_files(root):
    """The files git lists below root, or None when root is no checkout (or git is missing)."""
    if not os.path.exists(os.path.join(root, ".git")):
        return None
    try:
        p = subprocess.run(["git", "-C", root, "ls-files", "-z", "--cached", "--others",
                            "--exclude-standard"], capture_output=True)
    except OSError:
        return None
    if p.returncode != 0:
        return None
    return sorted(f for f in p.stdout.decode("utf-8", "replace").split("\0")
                  if f and os.path.isfile(os.path.join(root, f)))


def walked_files(root):
    out = []
    for top, dirs, files in os.walk(root):
        rel_top = os.path.relpath(top, root)
        at_top = rel_top == "."
        dirs[:] = sorted(d for d in dirs if d not in {".git", "__pycache__"} and
                         not (at_top and (d.startswith("build") or d == ".cache")))
        for f in sorted(files):
            out.append(os.path.normpath(os.path.join(rel_top, f)).replace(os.sep, "/"))
    return out


def tree_files(root):
    files = git_files(root)
    return walked_files(root) if files is None else files
