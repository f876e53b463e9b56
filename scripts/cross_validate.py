#!/usr/bin/env python3
"""Leave-one-group-out selection and figures for a recogniser's per-class score parameters.

What it measures: how the pipeline does on spaces whose labels were NOT used to choose its
parameters -- the figure to quote for new rooms.

1. For every point of a small grid (GRIDS below: a few values of the recogniser's spreads and
   its class competition), runs `furnihost eval --save-detections` once with that point set for
   every class (`--set STAGE.class_params=...`); the detection-time parameters need no
   retraining.
2. For each group of scans (a ScanNet space: every re-scan of one room is one group, so a room
   never tests itself) and each evaluated class, picks the grid point with the best AP25 on the
   other groups, then runs the graph once more on the held-out group with each class's chosen
   point (the classes' parameters mixed as they would ship) and pools those detections.
3. Per class on the pooled held-out detections: AP25, AP50 and the paper-rule AP; the operating
   threshold chosen on the other groups (the lowest score whose running precision is >= 0.75,
   max F1 when none is) and the precision / recall it gives on the held-out group.
4. Prints the in-sample choice (best grid point per class on all groups) with its thresholds as
   the class_params / thresholds JSON to paste into the graph.

usage: scripts/cross_validate.py --graph configs/scannet.json --dataset benchmarks/scannet_dev.json \\
           [--group 'scene(\\d{4})'] [--stage recognise] [--grid g8] [--out runs/cv] [--set TAG.PARAM=VALUE ...]
On 2 cores, g8 on the 18 ScanNet dev scans takes ~10 min for scannet.json and ~50 min for
scannet_ensemble.json (5 runs a detection).
The AP rules are those of `furnihost eval` (VoteNet's 3D IoU matching; the paper's centre rule);
tests/scripts/test_cross_validate.py checks them against hand-worked cases.
"""
import argparse
import itertools
import json
import os
import re
import subprocess
import sys
from collections import defaultdict

# Grids of the recogniser's per-class parameters (voters.catalog_shape names).
GRIDS = {
    "g6": {"sig_top_big": [0.1, 0.2], "sig_profile": [0.05, 0.08], "sig_surround": [0.15, 0.3, 0.6],
           "compete": [0, 1], "sig_long_big": [0.2, 0.5]},
    "tiny": {"sig_surround": [0.15, 0.6], "compete": [0, 1]},
    "none": {},  # the graph's own parameters: only the thresholds are chosen
}
# g6 and whether a class's models may hang above the floor (kitchen wall cabinets; 0 = they stand on it).
GRIDS["g6w"] = dict(GRIDS["g6"], wall_mount=[0, 3])
# g6 and the spread of a footprint wider than the model's (stop 39: chairs and tables 0.2 -> 0.4 in scannet.json).
GRIDS["g7"] = dict(GRIDS["g6"], sig_short_big=[0.2, 0.4])
# g7 and, for chairs only, the spread of more open floor seen under a proposal than under the model.
GRIDS["g8"] = dict(GRIDS["g7"], sig_floor_more=[0.2, 0.4])
# Keys a grid varies for some classes only: the other classes keep the key's first value (the
# recogniser's default), i.e. choose among the points that have it.
# Whether cabinets may hang on a wall, and how low (stop 41; the graph's other spreads kept).
GRIDS["wall"] = {"wall_mount": [0, 1.5, 2, 3], "wall_mount_bottom_m": [0, 1.2]}
CLASS_ONLY = {"g8": {"sig_floor_more": {"chair"}},
              "wall": {"wall_mount": {"cabinet"}, "wall_mount_bottom_m": {"cabinet"}}}


def load(path):
    with open(path) as f:
        return json.load(f)


# ---- matching and AP (as framework/src/eval/matching.cpp, metrics.cpp) -----------------------
def box_iou(a, b):
    """a, b: (lo, hi) triples of 3 numbers."""
    inter = 1.0
    for k in range(3):
        lo, hi = max(a[0][k], b[0][k]), min(a[1][k], b[1][k])
        if hi <= lo:
            return 0.0
        inter *= hi - lo
    va = vb = 1.0
    for k in range(3):
        va *= a[1][k] - a[0][k]
        vb *= b[1][k] - b[0][k]
    u = va + vb - inter
    return inter / u if u > 0 else 0.0


def match_scene(dets, gts, rule, threshold=0.25):
    """dets: [(score, cls, (lo, hi), centre)], gts: [(cls, (lo, hi), centre, radius)]. Returns a TP flag per
    detection. rule 'iou': VoteNet's eval_det_cls (each detection takes the gt of its class it overlaps most; TP
    when that IoU >= threshold and the gt is untaken); rule 'paper': the nearest untaken gt of its class whose
    centre lies strictly within its radius on the floor plane."""
    order = sorted(range(len(dets)), key=lambda i: -dets[i][0])
    taken = [False] * len(gts)
    tp = [False] * len(dets)
    for i in order:
        s, c, box, ctr = dets[i]
        best, best_v = -1, None
        for g, (gc, gbox, gctr, rad) in enumerate(gts):
            if gc != c:
                continue
            if rule == "iou":
                v = box_iou(box, gbox)
                if best_v is None or v > best_v:
                    best, best_v = g, v
            else:
                if taken[g]:
                    continue
                d = ((ctr[0] - gctr[0]) ** 2 + (ctr[1] - gctr[1]) ** 2) ** 0.5
                if d < rad and (best_v is None or d < best_v):
                    best, best_v = g, d
        if best < 0:
            continue
        if rule == "iou" and (best_v < threshold or taken[best]):
            continue
        taken[best] = True
        tp[i] = True
    return tp


def average_precision(scored, npos):
    """scored: [(score, tp)] pooled over scenes. VOC all-point interpolation, one point per distinct score."""
    if npos == 0:
        return float("nan")
    scored = sorted(scored, key=lambda x: -x[0])
    rec, prec, tp, fp = [], [], 0, 0
    for i, (s, t) in enumerate(scored):
        tp += t
        fp += not t
        if i + 1 < len(scored) and scored[i + 1][0] == s:
            continue
        rec.append(tp / npos)
        prec.append(tp / (tp + fp))
    for i in range(len(prec) - 2, -1, -1):
        prec[i] = max(prec[i], prec[i + 1])
    ap, prev = 0.0, 0.0
    for r, p in zip(rec, prec):
        ap += (r - prev) * p
        prev = r
    return ap


def operating_threshold(scored, npos, min_precision=0.75):
    """The lowest score whose running precision is >= min_precision (max F1 when none is)."""
    scored = sorted(scored, key=lambda x: -x[0])
    tp = fp = 0
    best_p, best_f = None, (-1.0, None)
    for i, (s, t) in enumerate(scored):
        tp += t
        fp += not t
        if i + 1 < len(scored) and scored[i + 1][0] == s:
            continue
        p = tp / (tp + fp)
        r = tp / npos if npos else 0.0
        f = 2 * p * r / (p + r) if p + r else 0.0
        if p >= min_precision:
            best_p = s
        if f > best_f[0]:
            best_f = (f, s)
    return best_p if best_p is not None else (best_f[1] if best_f[1] is not None else 1.0)


# ---- data ----------------------------------------------------------------------------------------
class Dataset:
    def __init__(self, path):
        m = load(path)
        base = os.path.dirname(os.path.abspath(path))
        self.classes = m["classes"]
        self.map = m.get("class_map", {})
        self.scenes = []  # (stem, gt objects)
        for sc in m["scenes"]:
            stem = os.path.splitext(os.path.basename(sc["scan"]))[0]
            gts = []
            for o in load(os.path.join(base, sc["gt"]))["objects"]:
                c = self.evaluated(o["class"])
                if c is None:
                    continue
                ctr, size = o["center"], o["size"]
                lo = tuple(ctr[k] - size[k] / 2 for k in range(3))
                hi = tuple(ctr[k] + size[k] / 2 for k in range(3))
                gts.append((c, (lo, hi), ctr, max(size[0], size[1]) / 2))
            self.scenes.append((stem, gts))

    def evaluated(self, cls):
        if cls in self.map:
            return self.map[cls]
        return cls if cls in self.classes else None


def detections_of(folder, stem, ds):
    out = []
    for d in load(os.path.join(folder, stem + ".json"))["detections"]:
        c = ds.evaluated(d["class"])
        if c is None or "box" not in d:
            continue
        out.append((d["score"], c, (tuple(d["box"]["aabb"]["min"]), tuple(d["box"]["aabb"]["max"])), d["center"]))
    return out


def run_eval(args, overrides, dataset, out):
    cmd = [args.furnihost, "eval", "--graph", args.graph, "--dataset", dataset, "--out", out, "-q",
           "--save-detections", "--name", "cv"]
    for o in list(getattr(args, "set", [])) + list(overrides):
        cmd += ["--set", o]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.stderr.write(r.stderr)
        raise SystemExit("cross_validate: furnihost eval failed: " + " ".join(cmd))
    seeds = os.listdir(os.path.join(out, "detections", "cv"))
    return os.path.join(out, "detections", "cv", sorted(seeds)[0])


def graph_class_params(args):
    """The graph's own per-class parameters of the recogniser (after extends): the keys a grid point does
    not set keep these values."""
    r = subprocess.run([args.furnihost, "validate", "--graph", args.graph, "--print"], capture_output=True, text=True)
    if r.returncode != 0:
        sys.stderr.write(r.stderr)
        raise SystemExit("cross_validate: furnihost validate failed for " + args.graph)
    stage = json.loads(r.stdout).get("stages", {}).get(args.stage, {})
    return stage.get("params", {}).get("class_params", {})


def class_figures(ds, dets_by_scene, scenes, cls):
    scored = {"iou25": [], "iou50": [], "paper": []}
    npos = 0
    for stem in scenes:
        gts = [g for g in ds_gt(ds, stem) if g[0] == cls]
        npos += len(gts)
        dets = [d for d in dets_by_scene[stem] if d[1] == cls]
        for key, rule, thr in (("iou25", "iou", 0.25), ("iou50", "iou", 0.5), ("paper", "paper", 0)):
            tp = match_scene(dets, gts, rule, thr)
            scored[key] += [(d[0], t) for d, t in zip(dets, tp)]
    return scored, npos


def ds_gt(ds, stem):
    for s, g in ds.scenes:
        if s == stem:
            return g
    return []


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--graph", required=True)
    ap.add_argument("--dataset", required=True)
    ap.add_argument("--stage", default="recognise", help="tag of the recogniser stage")
    ap.add_argument("--grid", default="g8", choices=sorted(GRIDS))
    ap.add_argument("--group", default=r"scene(\d{4})", help="regex: a scan's group is its first group in the file name")
    ap.add_argument("--furnihost", default="build/bin/furnihost")
    ap.add_argument("--out", default="runs/cross_validate")
    ap.add_argument("--min-precision", type=float, default=0.75)
    ap.add_argument("--set", action="append", default=[], metavar="TAG.PARAM=VALUE",
                    help="passed to every furnihost eval (e.g. ensemble.runs=3)")
    args = ap.parse_args()

    ds = Dataset(args.dataset)
    stems = [s for s, _ in ds.scenes]
    group = {}
    for s in stems:
        m = re.search(args.group, s)
        group[s] = (m.group(1) if m.groups() else m.group(0)) if m else s
    groups = sorted(set(group.values()))
    grid = GRIDS[args.grid]
    keys = sorted(grid)
    points = [dict(zip(keys, v)) for v in itertools.product(*(grid[k] for k in keys))]
    only = CLASS_ONLY.get(args.grid, {})

    def candidates(cls):
        """The grid points class `cls` may choose."""
        return [i for i, pt in enumerate(points)
                if all(cls in classes or pt[k] == grid[k][0] for k, classes in only.items())]
    fixed = graph_class_params(args)

    def with_fixed(choice):
        """class -> grid point, over the graph's own per-class parameters."""
        return {c: {**fixed.get(c, {}), **pt} for c, pt in choice.items()}
    print(f"cross_validate: {len(points)} grid points x {len(stems)} scans, {len(groups)} groups", file=sys.stderr)

    # 1. every grid point, every class set to it. The grid "none" sets nothing (the graph as it is,
    # whatever its recogniser: any graph, paper.json's Hough voter too) and its folds reuse these
    # detections, their parameters being the same.
    grid_free = not GRIDS[args.grid]
    per_point = []
    for i, pt in enumerate(points):
        cp = with_fixed({c: pt for c in ds.classes})
        folder = run_eval(args, [] if grid_free else [f"{args.stage}.class_params={json.dumps(cp)}"], args.dataset,
                          os.path.join(args.out, f"grid_{i:03d}"))
        per_point.append({s: detections_of(folder, s, ds) for s in stems})
        print(f"  grid point {i + 1}/{len(points)}", file=sys.stderr)

    def ap25(i, cls, scenes):
        sc, n = class_figures(ds, per_point[i], scenes, cls)
        return average_precision(sc["iou25"], n)

    # 2. leave one group out: choose per class, run the mixed choice on the held-out group
    held = {c: {"iou25": [], "iou50": [], "paper": []} for c in ds.classes}
    npos = defaultdict(int)
    op = {c: [0, 0] for c in ds.classes}  # tp, fp at the training-fold threshold
    base = load(args.dataset)
    for g in groups:
        test = [s for s in stems if group[s] == g]
        train = [s for s in stems if group[s] != g]
        choice, thr = {}, {}
        for c in ds.classes:
            scores = [(ap25(i, c, train), -i) for i in candidates(c)]
            best = max(scores, key=lambda x: (x[0] if x[0] == x[0] else -1, x[1]))
            i = -best[1]
            choice[c] = points[i]
            sc, n = class_figures(ds, per_point[i], train, c)
            thr[c] = operating_threshold(sc["iou25"], n, args.min_precision)
        sub = dict(base)
        sub["scenes"] = [sc for sc in base["scenes"] if os.path.splitext(os.path.basename(sc["scan"]))[0] in test]
        for sc in sub["scenes"]:  # paths relative to the original manifest
            for k in ("scan", "gt"):
                sc[k] = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(args.dataset)), sc[k]))
        mpath = os.path.join(args.out, f"fold_{g}.json")
        os.makedirs(args.out, exist_ok=True)
        with open(mpath, "w") as f:
            json.dump(sub, f)
        if grid_free:
            dets = {s: per_point[0][s] for s in test}
        else:
            folder = run_eval(args, [f"{args.stage}.class_params={json.dumps(with_fixed(choice))}"], mpath,
                              os.path.join(args.out, f"fold_{g}"))
            dets = {s: detections_of(folder, s, ds) for s in test}
        for c in ds.classes:
            sc, n = class_figures(ds, dets, test, c)
            npos[c] += n
            for k in held[c]:
                held[c][k] += sc[k]
            for s, t in sc["iou25"]:
                if s >= thr[c]:
                    op[c][0 if t else 1] += 1
        print(f"  fold {g}: {json.dumps(choice)}", file=sys.stderr)

    print("\nleave-one-group-out (held-out detections pooled), AP25 / AP50 / paper-rule AP, P / R at the "
          f"training folds' thresholds (precision >= {args.min_precision}):")
    heldout = {"graph": args.graph, "dataset": args.dataset, "grid": args.grid, "group": args.group,
               "groups": groups, "scenes": len(stems), "min_precision": args.min_precision, "classes": []}
    for c in ds.classes:
        h, n = held[c], npos[c]
        tp, fp = op[c]
        p = tp / (tp + fp) if tp + fp else float("nan")
        r = tp / n if n else float("nan")
        figures = {k: average_precision(h[k], n) for k in ("iou25", "iou50", "paper")}
        print(f"  {c:8s} ({n:3d} gt)  AP25 {figures['iou25']:.3f}  AP50 {figures['iou50']:.3f}"
              f"  AP {figures['paper']:.3f}   P {p:.2f} R {r:.2f}")
        heldout["classes"].append({"class": c, "gt": n, "ap25": figures["iou25"], "ap50": figures["iou50"],
                                   "ap": figures["paper"], "precision": p, "recall": r})
    # What update_results.sh puts in the README's held-out row (NaN -> null: JSON has no NaN).
    clean = json.loads(json.dumps(heldout).replace("NaN", "null"))
    tmp = os.path.join(args.out, "heldout.json.tmp")
    with open(tmp, "w") as f:
        json.dump(clean, f, indent=1)
    os.replace(tmp, os.path.join(args.out, "heldout.json"))

    # 4. in-sample choice
    ship, thresholds = {}, {}
    print("\nin-sample (all groups), best grid point per class:")
    for c in ds.classes:
        scores = [(ap25(i, c, stems), -i) for i in candidates(c)]
        i = -max(scores, key=lambda x: (x[0] if x[0] == x[0] else -1, x[1]))[1]
        ship[c] = points[i]
        sc, n = class_figures(ds, per_point[i], stems, c)
        thresholds[c] = round(operating_threshold(sc["iou25"], n, args.min_precision), 4)
        print(f"  {c:8s} AP25 {average_precision(sc['iou25'], n):.3f}  AP50 {average_precision(sc['iou50'], n):.3f}"
              f"  AP {average_precision(sc['paper'], n):.3f}")
    print(json.dumps({"class_params": with_fixed(ship), "thresholds": thresholds}))


if __name__ == "__main__":
    main()
