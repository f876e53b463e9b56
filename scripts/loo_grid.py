#!/usr/bin/env python3
"""Held-out AP25 of one class over saved runs of a few parameter settings (leave one group out).

Each run is a folder of per-scan detections (`furnihost eval --save-detections` writes them to
OUT/detections/<config>/<seed>/), all on one dataset, each with other detection-time parameters
(proposal or recogniser settings cross_validate.py's grids do not hold). For every group of scans
(--group: a regex whose first group names a scan's group; default: each scan its own), the run with
the best AP25 on the other groups is chosen (ties: the earlier run on the command line) and that
run's detections of the held-out group are pooled. A scan's detections depend only on the
parameters and that scan, so the pooled AP25 is the held-out AP25 of choosing the setting per fold.
Prints each run's in-sample AP25, how often each run was chosen, and the held-out AP25.

usage: scripts/loo_grid.py --dataset D.json --cls cabinet [--group '(sun\\d+)'] RUN_DIR [RUN_DIR ...]
"""
import argparse
import os
import re
import sys

sys.dont_write_bytecode = True  # no __pycache__ left in scripts/ by the import below
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cross_validate import Dataset, average_precision, class_figures, detections_of  # noqa: E402


def held_out(ds, dets, group, cls):
    """dets: per run, {scan: detections as cross_validate.detections_of gives}; group: {scan: group}.
    Returns (held-out AP25, per run how many groups chose it)."""
    stems = [s for s, _ in ds.scenes]

    def ap25(k, scenes):
        scored, npos = class_figures(ds, dets[k], scenes, cls)
        v = average_precision(scored["iou25"], npos)
        return -1.0 if v != v else v  # NaN (no object of the class) ranks last

    pooled, npos, chosen = [], 0, [0] * len(dets)
    for g in sorted(set(group.values())):
        train = [s for s in stems if group[s] != g]
        test = [s for s in stems if group[s] == g]
        scores = [ap25(k, train) for k in range(len(dets))]
        best = max(range(len(dets)), key=lambda k: (scores[k], -k))
        chosen[best] += 1
        scored, n = class_figures(ds, dets[best], test, cls)
        pooled += scored["iou25"]
        npos += n
    return average_precision(pooled, npos), chosen


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dataset", required=True)
    ap.add_argument("--cls", default="cabinet")
    ap.add_argument("--group", default="(.+)", help="regex: a scan's group is its first group in the file name")
    ap.add_argument("runs", nargs="+", help="folders of per-scan detections, one per setting")
    a = ap.parse_args()
    ds = Dataset(a.dataset)
    stems = [s for s, _ in ds.scenes]
    pattern = re.compile(a.group)
    group = {}
    for s in stems:
        m = pattern.search(s)
        if not m:
            raise SystemExit(f"{s}: --group {a.group!r} does not match")
        group[s] = m.group(1)
    dets = [{s: detections_of(r, s, ds) for s in stems} for r in a.runs]
    for k, r in enumerate(a.runs):
        scored, npos = class_figures(ds, dets[k], stems, a.cls)
        print(f"in-sample AP25 {average_precision(scored['iou25'], npos):.3f}  {r}")
    value, chosen = held_out(ds, dets, group, a.cls)
    for k, r in enumerate(a.runs):
        print(f"chosen for {chosen[k]} of {len(set(group.values()))} groups  {r}")
    npos = sum(1 for _, g in ds.scenes for o in g if o[0] == a.cls)
    print(f"held-out {a.cls} AP25 {value:.3f} ({npos} objects, {len(set(group.values()))} groups)")


if __name__ == "__main__":
    main()
