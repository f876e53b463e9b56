#!/usr/bin/env python3
"""Fits a graph's confidence calibration on labelled scans and writes it beside the graph; prints how
it does on spaces it was not fitted on.

A calibration file maps a detection's raw score (and, optionally, its evidence) to the probability
that it is a true positive at 3D IoU >= 0.25, per class:
  {"furnihost_calibration": 1, "method": "logistic", "fitted_on": {...data, revision, date, held-out
   figures...}, "classes": {"chair": {"features": ["log_score"], "coef": [1.9], "intercept": 2.4}, ...}}
confidence = 1 / (1 + exp(-(intercept + sum coef_k * feature_k))); features as calibration_fit.py.

1. Runs `furnihost eval --save-detections` of the graph on every dataset given (its raw scores:
   a calibration the graph already has changes no score).
2. Labels each detection of an evaluated class: a true positive when AP25's matching takes it (3D
   IoU >= 0.25 with an object of its class not taken by a higher-scored detection).
3. Leave one group out (a ScanNet space: every re-scan of a room is one group): per class, the map
   fitted on the other groups gives the held-out group's confidences; pooled, the expected
   calibration error (ECE, 10 bins) and precision / recall at confidence >= 0.5 on spaces the map
   did not see.
4. Fits each class's map on all groups and writes the calibration file, which records what it was
   fitted on (datasets and their hashes, the graph, git revision, date, command) and the held-out
   figures of step 3.

The graph's parameters stay as they are here: the held-out figures of step 3 are those of the
calibration alone (the recogniser's own parameters were chosen on the same spaces).

usage: scripts/calibrate.py --graph configs/scannet.json --dataset benchmarks/scannet_dev.json \\
           [--dataset more.json ...] [--write configs/calibration/scannet.json] [--group 'scene(\\d{4})']
           [--features log_score] [--work runs/calibrate] [--set TAG.PARAM=VALUE ...]
Without --write it only prints. Rerun it whenever the graph's detections change (its recogniser's
parameters, the proposer, the catalog).
"""
import argparse
import datetime
import json
import os
import re
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import calibration_fit as cf  # noqa: E402
import cross_validate as cv  # noqa: E402


def labelled(folder, ds, tag, scenes=None):
    """Detections of every scene of `ds` in `folder`: [(group key, class, score, evidence, tp)], and the
    number of ground-truth objects per class; with `scenes` (a list), each scene's (group key,
    ground truth, [its detections as dicts: cls, score, box, center, evidence]) appended to it."""
    rows, npos = [], {}
    for stem, gts in ds.scenes:
        dets = []
        for d in cv.load(os.path.join(folder, stem + ".json"))["detections"]:
            c = ds.evaluated(d["class"])
            if c is None or "box" not in d:
                continue
            box = (tuple(d["box"]["aabb"]["min"]), tuple(d["box"]["aabb"]["max"]))
            dets.append((d["score"], c, box, d["center"], d.get("evidence", {})))
        for cls in ds.classes:
            mine = [x for x in dets if x[1] == cls]
            truth = [g for g in gts if g[0] == cls]
            npos[cls] = npos.get(cls, 0) + len(truth)
            tp = cv.match_scene([x[:4] for x in mine], truth, "iou", 0.25)
            rows += [(tag(stem), cls, x[0], x[4], t) for x, t in zip(mine, tp)]
        if scenes is not None:
            scenes.append((tag(stem), gts, [{"score": x[0], "cls": x[1], "box": x[2], "center": x[3], "evidence": x[4]}
                                            for x in dets]))
    return rows, npos


def fit_class(rows, features, l2):
    x = [[cf.feature_value(f, r[2], r[3]) for f in features] for r in rows]
    y = [1 if r[4] else 0 for r in rows]
    return cf.fit_logistic(x, y, l2)


def held_out(rows, npos_by_group, classes, features, l2, scenes, parts):
    """Per class: [(confidence, tp)] of every group predicted by the map fitted on the others. With
    `parts` (the graph's calibration.part_of: pairs, share, min_confidence) the host's DropParts runs on
    each scan with those confidences first, and what it keeps is matched anew: the figures of the
    graph as it runs."""
    groups = sorted(set(r[0] for r in rows) | set(npos_by_group))
    out = {c: [] for c in classes}
    for g in groups:
        maps = {}
        for c in classes:
            train = [r for r in rows if r[0] != g and r[1] == c]
            if any(r[0] == g and r[1] == c for r in rows):
                maps[c] = fit_class(train, features, l2)
        for key, gts, dets in scenes:
            if key != g:
                continue
            for d in dets:
                m = maps.get(d["cls"])
                d["confidence"] = cf.confidence(m[0], m[1], [cf.feature_value(f, d["score"], d["evidence"]) for f in features]) \
                    if m else None
            kept = cf.drop_parts(dets, parts[0], parts[1], parts[2]) if parts and parts[0] else dets
            for c in classes:
                mine = [d for d in kept if d["cls"] == c]
                tp = cv.match_scene([(d["score"], c, d["box"], d["center"]) for d in mine], [x for x in gts if x[0] == c],
                                    "iou", 0.25)
                out[c] += [(d["confidence"], t) for d, t in zip(mine, tp)]
    return out


def graph_calibration(args):
    """The graph's calibration section as furnihost resolves it (with --set), or {}."""
    cmd = [args.furnihost, "validate", "--graph", args.graph, "--print"]
    for o in args.set:
        cmd += ["--set", o]
    r = subprocess.run(cmd, capture_output=True, text=True, env=cv.child_env())
    if r.returncode != 0:
        sys.stderr.write(r.stderr)
        raise SystemExit("calibrate: furnihost validate failed: " + " ".join(cmd))
    return json.loads(r.stdout[r.stdout.index("{"):]).get("calibration") or {}


def git_revision(near):
    try:
        rev = subprocess.run(["git", "-C", near, "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", near, "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True).stdout.strip()
        return rev + (" + uncommitted changes" if dirty else "") if rev else "unknown"
    except OSError:
        return "unknown"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--graph", required=True)
    ap.add_argument("--dataset", action="append", required=True, help="dataset manifest (repeatable)")
    ap.add_argument("--write", help="calibration file to write (e.g. configs/calibration/scannet.json)")
    ap.add_argument("--group", default=r"scene(\d{4})", help="regex: a scan's group is its first group in the file name")
    ap.add_argument("--features", default=",".join(cf.DEFAULT_FEATURES),
                    help="comma-separated: log_score, evidence:NAME, log_evidence:NAME")
    ap.add_argument("--l2", type=float, default=0.01, help="L2 penalty on the standardised slopes")
    ap.add_argument("--min-confidence", type=float, default=0.5)
    ap.add_argument("--furnihost", default="build/bin/furnihost")
    ap.add_argument("--work", default="runs/calibrate", help="folder for the eval runs")
    ap.add_argument("--set", action="append", default=[], metavar="TAG.PARAM=VALUE", help="passed to every furnihost eval")
    args = ap.parse_args()
    features = [f for f in args.features.split(",") if f]
    for f in features:
        cf.feature_value(f, 1.0, {})  # unknown names fail here

    # The maps are fitted on every detection the recogniser gives (the graph's part_of rule off): the
    # host applies them to those, then drops parts (calibration.part_of); the held-out figures run
    # that rule with each space's held-out confidences.
    section = graph_calibration(args)
    pairs = cf.part_of_pairs(section.get("part_of", ""))
    parts = (pairs, float(section.get("part_share", 0.5)), args.min_confidence) if pairs else None
    raw = ['calibration.part_of=""'] if pairs else []
    rows, npos, npos_by_group, sources, classes, scenes = [], {}, {}, [], [], []
    for k, path in enumerate(args.dataset):
        ds = cv.Dataset(path)
        for c in ds.classes:
            if c not in classes:
                classes.append(c)
        out = os.path.join(args.work, "set_%d" % k)
        folder = cv.run_eval(argparse.Namespace(furnihost=args.furnihost, graph=args.graph, set=args.set), raw, path, out)

        def tag(stem, k=k):
            m = re.search(args.group, stem)
            return "%d:%s" % (k, (m.group(1) if m.groups() else m.group(0)) if m else stem)
        r, n = labelled(folder, ds, tag, scenes)
        rows += r
        for c, v in n.items():
            npos[c] = npos.get(c, 0) + v
        for stem, gts in ds.scenes:
            g = tag(stem)
            for gt in gts:
                npos_by_group.setdefault(g, {}).setdefault(gt[0], 0)
                npos_by_group[g][gt[0]] += 1
        summary = cv.load(os.path.join(out, "summary.json"))
        sources.append({"path": path, "hash": summary["dataset"]["hash"], "scenes": len(ds.scenes)})
    groups = sorted(set(npos_by_group) | set(r[0] for r in rows))
    print("calibrate: %d detections of %s on %d scans in %d groups" %
          (len(rows), ", ".join(classes), sum(s["scenes"] for s in sources), len(groups)), file=sys.stderr)

    # Held out: each group's confidences from the map fitted on the other groups.
    pooled = held_out(rows, npos_by_group, classes, features, args.l2, scenes, parts)
    if parts:
        print("held out with the graph's part_of rule (%s, share %.2f) on each space's held-out confidences" %
              (", ".join("%s:%s" % p for p in pairs), parts[1]), file=sys.stderr)
    loso = {}
    print("\nleave one group out (the map fitted on the other groups), at confidence >= %.2f, IoU 0.25:" % args.min_confidence)
    everything = []
    for c in classes:
        ece, _ = cf.reliability(pooled[c])
        tp, fp, p, r = cf.working_point(pooled[c], npos.get(c, 0), args.min_confidence)
        everything += pooled[c]
        loso[c] = {"gt": npos.get(c, 0), "detections": len(pooled[c]), "ece": ece, "tp": tp, "fp": fp,
                   "precision": p, "recall": r}
        print("  %-8s (%3d gt, %4d detections)  P %.3f  R %.3f  (TP %d, FP %d)  ECE %.3f" %
              (c, npos.get(c, 0), len(pooled[c]), p, r, tp, fp, ece))
    ece_all, bins = cf.reliability(everything)
    print("  all classes: ECE %.3f over %d detections" % (ece_all, len(everything)))
    for lo, hi, n, mc, acc in bins:
        if n:
            print("    confidence %.1f-%.1f: %4d detections, mean %.3f, true %.3f" % (lo, hi, n, mc, acc))

    maps = {}
    for c in classes:
        mine = [r for r in rows if r[1] == c]
        if not mine:
            continue
        coef, b = fit_class(mine, features, args.l2)
        maps[c] = {"features": features, "coef": [round(v, 6) for v in coef], "intercept": round(b, 6),
                   "detections": len(mine), "true": sum(1 for r in mine if r[4])}
    here = os.path.dirname(os.path.abspath(args.graph))
    now = datetime.datetime.now(datetime.timezone.utc)
    data = "; ".join("%s (%d scans)" % (s["path"], s["scenes"]) for s in sources)
    doc = {
        "furnihost_calibration": 1,
        "target": "probability that the detection is a true positive: its box overlaps a ground-truth object of its "
                  "class at 3D IoU >= 0.25 that no higher-scored detection took (AP25's matching)",
        "method": "logistic",
        "fitted_on": {"data": data, "datasets": sources, "groups": len(groups), "group_regex": args.group,
                      "graph": os.path.relpath(os.path.abspath(args.graph)), "overrides": args.set,
                      "part_of": section.get("part_of", ""),
                      "revision": git_revision(here), "date": now.strftime("%Y-%m-%d"),
                      "command": " ".join(["scripts/calibrate.py"] + sys.argv[1:]), "l2": args.l2,
                      "held_out": {"min_confidence": args.min_confidence, "ece_all": ece_all, "classes": loso}},
        "classes": maps,
    }
    clean = json.loads(json.dumps(doc).replace("NaN", "null"))
    if args.write:
        tmp = args.write + ".tmp"
        with open(tmp, "w") as f:
            json.dump(clean, f, indent=1)
            f.write("\n")
        os.replace(tmp, args.write)
        print("-> " + args.write)
    else:
        print(json.dumps(clean["classes"]))


if __name__ == "__main__":
    main()
