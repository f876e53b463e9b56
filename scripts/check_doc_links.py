#!/usr/bin/env python3
"""Checks the relative links of the project's Markdown files: every [text](path) and
[text](path#anchor) names a file (or folder) that exists, and an anchor names a heading of
the target file (GitHub's slugs). Links to http(s)/mailto and to data outside the repository
(../shared/...) are not checked.

  scripts/check_doc_links.py [FILE.md ...]    default: every tracked *.md file

Prints one line per broken link (file:line: link: why) and exits 1 if there is any, 0 otherwise.
"""
import pathlib
import re
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
LINK = re.compile(r"!?\[(?:[^\]\[]|\[[^\]]*\])*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
FENCE = re.compile(r"^\s*(```|~~~)")


def slug(heading):
    """GitHub's anchor of a heading: lower case, punctuation but '-' and '_' dropped, spaces -> '-'."""
    text = re.sub(r"<[^>]+>", "", heading).strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path, cache={}):
    if path not in cache:
        seen, found = {}, set()
        in_fence = False
        for line in path.read_text(encoding="utf-8").splitlines():
            if FENCE.match(line):
                in_fence = not in_fence
                continue
            m = None if in_fence else re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
            if m:
                s = slug(m.group(1))
                n = seen.get(s, 0)
                seen[s] = n + 1
                found.add(s if n == 0 else f"{s}-{n}")
        found.update(re.findall(r'<a\s+(?:name|id)="([^"]+)"', path.read_text(encoding="utf-8")))
        cache[path] = found
    return cache[path]


def check(md):
    problems = []
    in_fence = False
    for number, line in enumerate(md.read_text(encoding="utf-8").splitlines(), 1):
        if FENCE.match(line):
            in_fence = not in_fence
            continue
        if in_fence:
            continue
        for target in LINK.findall(re.sub(r"`[^`]*`", "", line)):
            if re.match(r"^[a-z]+:", target):
                continue
            path_part, _, anchor = target.partition("#")
            dest = (md.parent / path_part).resolve() if path_part else md.resolve()
            try:
                dest.relative_to(ROOT)
            except ValueError:
                continue  # outside the repository (e.g. ../shared/data): not ours to check
            where = f"{md.relative_to(ROOT)}:{number}: {target}"
            if not dest.exists():
                problems.append(f"{where}: no such file")
            elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
                problems.append(f"{where}: no heading with anchor #{anchor} in {dest.relative_to(ROOT)}")
    return problems


SKIP = re.compile(r"^(build.*|\.git|runs|furnihost-out|_deps)$")


def project_files(pattern):
    """The tracked files matching `pattern` (git ls-files), or, outside a git checkout, the files
    under the project root but in build folders, run folders and .git."""
    try:
        listed = subprocess.run(["git", "-C", str(ROOT), "ls-files", pattern], capture_output=True,
                                text=True, check=True).stdout.split()
        return [ROOT / f for f in listed]
    except (OSError, subprocess.CalledProcessError):
        return [f for f in ROOT.rglob(pattern)
                if not any(SKIP.match(part) for part in f.relative_to(ROOT).parts[:-1])]


def main(argv):
    if argv:
        files = [pathlib.Path(a).resolve() for a in argv]
    else:
        files = project_files("*.md")
    problems = [p for f in files if f.exists() for p in check(f)]
    for p in problems:
        print(p)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
