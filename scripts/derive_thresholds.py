#!/usr/bin/env python3
"""Re-derives a graph's per-class voter thresholds from a dataset (the procedure documented in
plugins/common/voting/voting.hpp).

1. Runs `furnihost` on every scene of the manifest with the graph's voter thresholds set to 0
   and without fitters (selection at threshold t equals selection at 0 filtered to score >= t).
2. Matches the hypotheses to the ground truth with the paper's rule (Sect. VII-A: same class
   after the manifest's class_map, floor-plane centre within half the object's max(x, y) size,
   strongest detection first, one detection per object).
3. Per evaluated class, picks the one threshold that maximises its F1 and gives it to every
   voter class that maps to it (armchair and stool -> chair, desk -> table). Candidates are the
   0th, 5th, ..., 90th percentiles of those classes' scores, so no class is switched off and a
   handful of dev objects cannot pick an extreme value. `--per voter-class` instead tunes each
   voter class on its own (coordinate ascent, 3 rounds): more free thresholds, and on the
   ScanNet dev set they generalise worse (leave-one-space-out F1, scannet.json: chair 0.195
   against 0.263 with one threshold per evaluated class, table 0.175 against 0.194).

usage: scripts/derive_thresholds.py --graph configs/scannet.json --dataset benchmarks/scannet_dev.json \
           [--cross-validate 'scene(\\d{4})']
Prints the thresholds as JSON and the precision / recall / F1 before and after; with
--cross-validate also the leave-one-group-out figures (what to expect on rooms not tuned on).
"""
import argparse
import json
import math
import os
import shutil
import re
import subprocess
import sys
import tempfile
from collections import defaultdict


def load(path):
    with open(path) as f:
        return json.load(f)


def prf(tp, fp, ng):
    """Precision, recall and F1 of tp true and fp false detections of ng objects (0 when undefined)."""
    p = tp / (tp + fp) if tp + fp else 0.0
    r = tp / ng if ng else 0.0
    return p, r, 2 * p * r / (p + r) if p + r else 0.0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--graph", required=True)
    ap.add_argument("--dataset", required=True)
    ap.add_argument("--furnihost", default="build/bin/furnihost")
    ap.add_argument("--vote-stage", default="vote", help="tag of the voter stage in the graph")
    ap.add_argument("--fit-stages", default="fit,refine", help="fitter tags removed for the sweep")
    ap.add_argument("--per", choices=["class", "voter-class"], default="class",
                    help="one threshold per evaluated class (shared by the voter classes mapping to it), "
                         "or one per voter class")
    ap.add_argument("--cross-validate", metavar="REGEX",
                    help="also estimate how the thresholds generalise: leave one group of scans out at a time, "
                         "derive on the rest, count on it; a scan's group is REGEX's first group (or match) in "
                         "its file name, e.g. 'scene(\\d{4})' keeps the scans of one ScanNet space together")
    args = ap.parse_args()

    manifest = load(args.dataset)
    base = os.path.dirname(os.path.abspath(args.dataset))
    cmap = manifest.get("class_map", {})
    classes = manifest["classes"]
    mapped = lambda c: cmap.get(c, c)

    graph = os.path.abspath(args.graph)
    tmp = tempfile.mkdtemp(prefix="furnihost-thresholds-")
    # The sweep config sits beside the graph so its relative paths resolve the same way.
    sweep = os.path.join(os.path.dirname(graph), ".derive_thresholds.%d.json" % os.getpid())
    stages = {args.vote_stage: {"params": {"thresholds": {}, "default_threshold": 0}}}
    for tag in args.fit_stages.split(","):
        if tag:
            stages[tag] = None
    # Explicit zeros: a merge patch of {} would keep the graph's thresholds.
    g = load(graph)
    old = g.get("stages", {}).get(args.vote_stage, {}).get("params", {}).get("thresholds", {})
    cfg = graph
    while not old and "extends" in load(cfg):
        cfg = os.path.join(os.path.dirname(cfg), load(cfg)["extends"])
        old = load(cfg).get("stages", {}).get(args.vote_stage, {}).get("params", {}).get("thresholds", {})
    stages[args.vote_stage]["params"]["thresholds"] = {k: 0 for k in old}
    with open(sweep, "w") as f:
        json.dump({"extends": os.path.basename(graph), "stages": stages}, f)
    scenes = []
    try:
        for i, sc in enumerate(manifest["scenes"]):
            out = os.path.join(tmp, str(i))
            cmd = [args.furnihost, "-q", "--graph", sweep, os.path.join(base, sc["scan"]), "--out", out]
            if "origin" in sc:
                cmd += ["--origin", ",".join(str(v) for v in sc["origin"])]
            print("scene %d/%d: %s" % (i + 1, len(manifest["scenes"]), sc["scan"]), file=sys.stderr)
            run = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
            if run.returncode != 0:  # its warnings (no fitter in the sweep graph) only matter then
                sys.stderr.write(run.stderr)
                raise subprocess.CalledProcessError(run.returncode, cmd)
            truth = load(os.path.join(base, sc["gt"]))["objects"]
            gt = [(mapped(o["class"]), o["center"], max(o["size"][0], o["size"][1]) / 2) for o in truth]
            gt = [t for t in gt if t[0] in classes]
            dets = [d for d in load(os.path.join(out, "detections.json"))["detections"] if mapped(d["class"]) in classes]
            scenes.append((gt, dets))
    finally:
        os.remove(sweep)
        shutil.rmtree(tmp, ignore_errors=True)

    def evaluate(th, scenes=scenes):
        tp, fp, ng = defaultdict(int), defaultdict(int), defaultdict(int)
        for gt, dets in scenes:
            for t in gt:
                ng[t[0]] += 1
            used = set()
            for d in sorted((d for d in dets if d["score"] >= th.get(d["class"], 0)), key=lambda d: -d["score"]):
                c = mapped(d["class"])
                best = None
                for i, (gc, ctr, r) in enumerate(gt):
                    if gc != c or i in used:
                        continue
                    dist = math.hypot(d["center"][0] - ctr[0], d["center"][1] - ctr[1])
                    if dist < r and (best is None or dist < best[0]):
                        best = (dist, i)
                if best:
                    used.add(best[1])
                    tp[c] += 1
                else:
                    fp[c] += 1
        # Per class: precision, recall, F1, TP, FP, number of objects.
        return {c: prf(tp[c], fp[c], ng[c]) + (tp[c], fp[c], ng[c]) for c in classes}

    def derive(scenes):
        voter_classes = sorted({d["class"] for _, ds in scenes for d in ds})
        th = {c: 0.0 for c in voter_classes}
        # Groups of voter classes that share a threshold.
        if args.per == "class":
            groups = [[vc for vc in voter_classes if mapped(vc) == c] for c in classes]
        else:
            groups = [[vc] for vc in voter_classes]
        groups = [g for g in groups if g]
        for _ in range(3 if args.per == "voter-class" else 1):
            for group in groups:
                mc = mapped(group[0])
                s = sorted(d["score"] for _, ds in scenes for d in ds if d["class"] in group)
                best = (evaluate(th, scenes)[mc][2], th[group[0]])
                for q in range(0, 91, 5):
                    t = s[int(q / 100 * (len(s) - 1))]
                    trial = dict(th, **{vc: t for vc in group})
                    f1 = evaluate(trial, scenes)[mc][2]
                    if f1 > best[0] + 1e-9:
                        best = (f1, t)
                for vc in group:
                    th[vc] = best[1]
        return th

    th = derive(scenes)
    before = evaluate({c: 0.0 for c in th})
    after = evaluate(th)
    for c in classes:
        print("%-8s threshold 0: P %.3f R %.3f F1 %.3f (TP %d FP %d)  ->  derived: P %.3f R %.3f F1 %.3f (TP %d FP %d)"
              % ((c,) + before[c][:5] + after[c][:5]), file=sys.stderr)
    if args.cross_validate:
        # Leave one group out: thresholds derived without the group's scans, counted on them.
        key = re.compile(args.cross_validate)
        names = [os.path.basename(sc["scan"]) for sc in manifest["scenes"]]
        keys = []
        for n in names:
            m = key.search(n)
            keys.append((m.group(1) if m.groups() else m.group(0)) if m else n)
        tp, fp, ng = defaultdict(int), defaultdict(int), defaultdict(int)
        for g in sorted(set(keys)):
            train = [sc for sc, k in zip(scenes, keys) if k != g]
            test = [sc for sc, k in zip(scenes, keys) if k == g]
            if not train:
                continue
            res = evaluate(derive(train), test)
            for c in classes:
                tp[c] += res[c][3]
                fp[c] += res[c][4]
                ng[c] += res[c][5]
        print("leave-one-group-out over %d groups (--cross-validate %s):" % (len(set(keys)), args.cross_validate),
              file=sys.stderr)
        for c in classes:
            print("%-8s held out: P %.3f R %.3f F1 %.3f (TP %d FP %d of %d)"
                  % ((c,) + prf(tp[c], fp[c], ng[c]) + (tp[c], fp[c], ng[c])), file=sys.stderr)
    print(json.dumps({k: round(v, 2) for k, v in th.items()}))


if __name__ == "__main__":
    main()
