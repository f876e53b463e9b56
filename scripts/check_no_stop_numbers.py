#!/usr/bin/env python3
"""The project's text says what the product is, not when it got so: no "stop <number>" (any case)
in any tracked file, code, docs, scripts or configs alike. History and measurements go to commit
messages and to the dated records of docs/experiments/.

  scripts/check_no_stop_numbers.py

Prints file:line: text for every hit and exits 1 if there is any, 0 otherwise.
"""
import re
import sys

from check_doc_links import ROOT, project_files

PATTERN = re.compile(r"\bstop\s+[0-9]+", re.IGNORECASE)


def main():
    hits = []
    for path in project_files("*"):
        if not path.is_file():
            continue
        try:
            text = path.read_text(encoding="utf-8")
        except (UnicodeDecodeError, OSError):
            continue  # binary files (images, meshes)
        for number, line in enumerate(text.splitlines(), 1):
            if PATTERN.search(line):
                hits.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()[:120]}")
    for h in hits:
        print(h)
    return 1 if hits else 0


if __name__ == "__main__":
    sys.exit(main())
