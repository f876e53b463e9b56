#!/usr/bin/env python3
"""Files of one concern: no tracked C++ or Python source (.cpp, .hpp, .py) is longer than
MAX_LINES lines, but the ones named in EXEMPT. A file that outgrows the limit is split along its
concerns (one file per section: a plugin's private header and a .cpp per step), not exempted.

  scripts/check_file_sizes.py [--max N]

Prints path: lines for every file over the limit and exits 1 if there is any, 0 otherwise.
"""
import argparse
import sys

from check_doc_links import ROOT, project_files

MAX_LINES = 700
SUFFIXES = (".cpp", ".hpp", ".py")

# The only files allowed past MAX_LINES, each with its reason.
EXEMPT = {
    # The scan readers: one reader per format (PLY, PCD, XYZ, ...) behind one dispatcher.
    "framework/src/sdk/scan_reader.cpp": "scan readers",
}


def count_lines(path):
    with open(path, "rb") as f:
        return sum(1 for _ in f)


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max", type=int, default=MAX_LINES, help="the most lines a file may have")
    args = parser.parse_args(argv)
    over = []
    for path in project_files("*"):
        if path.suffix not in SUFFIXES or not path.is_file():
            continue
        rel = path.relative_to(ROOT).as_posix()
        if rel in EXEMPT:
            continue
        n = count_lines(path)
        if n > args.max:
            over.append((n, rel))
    for n, rel in sorted(over, reverse=True):
        print(f"{rel}: {n} lines (> {args.max}): split it along its concerns")
    return 1 if over else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
