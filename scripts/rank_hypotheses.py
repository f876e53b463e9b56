#!/usr/bin/env python3
"""Which hypotheses of one class outrank its true objects, and how far removing each kind could lift AP.

Every hypothesis of --cls in a graph's saved detections (accepted or not: AP ranks them all) is
ranked by score, pooled over the dataset as the evaluation ranks them, and listed with: whether it
is a true positive (AP25 matching), the evaluated ground-truth object it overlaps most in its scan
(3D IoU >= 0.25, else "none"), its model, box size, top above the ground, and the evidence named by
--evidence. With --rooms (the room dataset views were cut from by scripts/make_scannet_views.py),
also the room's ground-truth object it overlaps most: a view keeps only objects it sees 30 % of,
so "none" in the view but "chair" in the room is a chair the view's ground truth leaves out.

Summary:
  - the false positives above the k-th true positive, by the ground-truth class they overlap;
  - the AP25 with each kind of false positive taken out (an oracle: the most a rule that removes
    exactly that kind, and no true positive, could lift AP25 to);
  - with --factor EXPR, the AP25 with every score multiplied by EXPR, a Python expression of the
    hypothesis (`score`, `ev` its evidence dict, `size` its box size, `top` its top above the
    ground, `model`), to try a scoring rule on saved detections before implementing it. Rescoring
    inside the fitter also changes which hypotheses are searched and explained away, so this is
    an estimate; with thresholds the only thing chosen per fold (`cross_validate.py --grid none`)
    the pooled AP25 of the saved detections is the held-out AP25.

usage: scripts/rank_hypotheses.py --dataset VIEWS/dataset.json --detections DIR [--cls chair] [--top 40]
       [--rooms benchmarks/scannet_dev.json] [--evidence recogniser_score,syn_compete] [--geometry] [--factor EXPR]
DIR: per-scan detections as `furnihost eval --save-detections` (OUT/detections/<config>/<seed>/) or
`cross_validate.py` (OUT/grid_000/detections/cv/<seed>/) write them.
"""
import argparse
import json
import math
import os
import re
import sys
from collections import Counter

sys.dont_write_bytecode = True  # no __pycache__ left in scripts/ by the import below
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cross_validate import Dataset, average_precision, box_iou, load, match_scene  # noqa: E402
from diagnose_misses import read_xyz  # noqa: E402

FRAME = re.compile(r"in (\S+) at \(([-\d.]+), ([-\d.]+), ([-\d.]+)\) looking along ([xy]) \(([+-])\)")


def room_box(frame, box):
    """The room's axis-aligned box of a view's box, from the view's `frame` as make_scannet_views.py
    writes it (camera position and heading along one room axis); None when the frame says neither."""
    m = FRAME.search(frame or "")
    if not m:
        return None, None
    cam = [float(m.group(k)) for k in (2, 3, 4)]
    s = 1.0 if m.group(6) == "+" else -1.0
    fx, fy = (s, 0.0) if m.group(5) == "x" else (0.0, s)
    rx, ry = fy, -fx  # right = forward x up, as make_scannet_views.box_in_view
    xs, ys = [], []
    for u in (box[0][0], box[1][0]):
        for v in (box[0][1], box[1][1]):
            xs.append(cam[0] + u * rx + v * fx)
            ys.append(cam[1] + u * ry + v * fy)
    return m.group(1), ((min(xs), min(ys), box[0][2] + cam[2]), (max(xs), max(ys), box[1][2] + cam[2]))


def side_seat(points, det, strip=0.3, cell=0.05, seat=(0.3, 0.6)):
    """The share of the two strips beside a hypothesis (along its width, `strip` wide, one `cell` off
    its box, as deep as it; the larger of the two) whose highest point lies at seat height above
    the ground: a seat that goes on past a chair's side (a sofa read as an armchair at one end)
    against the floor, a gap or an armrest beside a chair. `det`: a saved detection (its `facing`
    and box)."""
    box = det["box"]
    c, f = box["center"], det.get("facing") or [math.cos(box["yaw"]), math.sin(box["yaw"]), 0.0]
    w = (-f[1], f[0])
    depth = max(abs((q[0] - c[0]) * f[0] + (q[1] - c[1]) * f[1]) for q in box["corners"])
    width = max(abs((q[0] - c[0]) * w[0] + (q[1] - c[1]) * w[1]) for q in box["corners"])
    ground = box["aabb"]["min"][2] - box.get("bottom_above_ground", 0.0)
    top = {}
    for p in points:
        dx, dy = p[0] - c[0], p[1] - c[1]
        u, v = dx * w[0] + dy * w[1], dx * f[0] + dy * f[1]
        if abs(v) > depth or not width + cell < abs(u) <= width + cell + strip:
            continue
        k = (u > 0, math.floor(u / cell), math.floor(v / cell))
        top[k] = max(top.get(k, -math.inf), p[2] - ground)
    cells = max(1.0, (2 * depth / cell) * (strip / cell))
    return max(sum(1 for k, h in top.items() if k[0] == side and seat[0] <= h < seat[1]) / cells
               for side in (False, True))


def best_overlap(box, objects):
    """(class, IoU) of the object of [(class, (lo, hi))] `box` overlaps most; ("none", IoU) under 0.25."""
    best = max([(box_iou(box, b), c) for c, b in objects] + [(0.0, "none")])
    return (best[1] if best[0] >= 0.25 else "none"), best[0]


def room_objects(rooms_manifest):
    """Room stem -> [(evaluated class, (lo, hi))] of every object of the room dataset."""
    ds = Dataset(rooms_manifest)
    return {stem: [(g[0], g[1]) for g in gts] for stem, gts in ds.scenes}


def hypotheses(ds, folder, cls, rooms=None, geometry=False):
    """Every hypothesis of cls in the saved detections of `ds` (as gt_dataset gives it), with its TP
    flag and what it overlaps (and, with geometry, side_seat from its scan), best first."""
    rows = []
    for stem, gts in ds.scenes:
        path = os.path.join(folder, stem + ".json")
        if not os.path.exists(path):
            continue
        doc = load(path)
        mine = [d for d in doc["detections"] if "box" in d and ds.evaluated(d["class"]) == cls]
        boxes = [(tuple(d["box"]["aabb"]["min"]), tuple(d["box"]["aabb"]["max"])) for d in mine]
        tp = match_scene([(d["score"], cls, b, d["center"]) for d, b in zip(mine, boxes)],
                         [g for g in gts if g[0] == cls], "iou", 0.25)
        frame = load(ds.gt_paths[stem]).get("frame") if rooms is not None else None
        points = read_xyz(ds.scan_paths[stem]) if geometry and mine else None
        for d, b, t in zip(mine, boxes, tp):
            row = {"stem": stem, "score": d["score"], "tp": bool(t), "model": d.get("model", ""),
                   "size": d["box"]["size"], "ev": d.get("evidence", {}),
                   "top": d["box"]["size"][2] + d["box"].get("bottom_above_ground", 0.0),
                   "verified": bool(d.get("verified")), "box": b}
            row["gt"], row["iou"] = best_overlap(b, [(g[0], g[1]) for g in gts])
            row["room_gt"] = ""
            row["side"] = side_seat(points, d) if points is not None else float("nan")
            if rooms is not None:
                room, rb = room_box(frame, b)
                if room in rooms:
                    row["room_gt"] = best_overlap(rb, rooms[room])[0]
            rows.append(row)
    rows.sort(key=lambda r: -r["score"])
    return rows


def ap25(rows, npos, key=lambda r: r["score"]):
    return average_precision([(key(r), r["tp"]) for r in rows], npos)


def kind(r):
    """What a false positive lies on: the view's ground-truth class, or "none" (+ the room's class)."""
    if r["gt"] != "none" or not r["room_gt"] or r["room_gt"] == "none":
        return r["gt"]
    return "none/room " + r["room_gt"]


def oracle(rows, npos):
    """AP25 with each kind of false positive taken out, each kind alone and all but one."""
    kinds = sorted({kind(r) for r in rows if not r["tp"]})
    out = [(k, ap25([r for r in rows if r["tp"] or kind(r) != k], npos)) for k in kinds]
    if len(kinds) > 1:
        for keep in kinds:
            out.append((f"all but {keep}", ap25([r for r in rows if r["tp"] or kind(r) == keep], npos)))
    return out


def gt_dataset(path):
    """The dataset, with each scan's ground-truth and scan paths by stem."""
    ds = Dataset(path)
    base = os.path.dirname(os.path.abspath(path))
    ds.gt_paths, ds.scan_paths = {}, {}
    for sc in load(path)["scenes"]:
        stem = os.path.splitext(os.path.basename(sc["scan"]))[0]
        ds.gt_paths[stem] = os.path.join(base, sc["gt"])
        ds.scan_paths[stem] = os.path.join(base, sc["scan"])
    return ds


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dataset", required=True)
    ap.add_argument("--detections", required=True)
    ap.add_argument("--cls", default="chair")
    ap.add_argument("--top", type=int, default=40, help="hypotheses listed (the true positives below are listed too)")
    ap.add_argument("--rooms", help="the room dataset the views were cut from (make_scannet_views.py's --dataset)")
    ap.add_argument("--evidence", default="recogniser_score,syn_explained_share,syn_compete,syn_new_share",
                    help="evidence keys listed per hypothesis")
    ap.add_argument("--geometry", action="store_true",
                    help="read the scans for side_seat (`side` in --factor; listed); binary little-endian PLY")
    ap.add_argument("--factor", action="append", default=[], help="Python expression re-weighting every score")
    args = ap.parse_args()
    ds = gt_dataset(args.dataset)
    npos = sum(1 for _, gts in ds.scenes for g in gts if g[0] == args.cls)
    rooms = room_objects(args.rooms) if args.rooms else None
    rows = hypotheses(ds, args.detections, args.cls, rooms, args.geometry)
    if not rows:
        raise SystemExit(f"no {args.cls} hypotheses under {args.detections}")
    keys = [k for k in args.evidence.split(",") if k]
    print(f"{args.cls}: {npos} ground-truth objects, {len(rows)} hypotheses, AP25 {ap25(rows, npos):.3f}")
    print("rank score    tp  on (IoU)        room     size            top   side  model                "
          + " ".join(k.replace("syn_", "")[:10] for k in keys))
    for i, r in enumerate(rows):
        if i >= args.top and not r["tp"]:
            continue
        size = "x".join(f"{s:.2f}" for s in r["size"])
        ev = " ".join(f"{r['ev'].get(k, float('nan')):10.3g}" for k in keys)
        print(f"{i + 1:4d} {r['score']:.5f} {'TP' if r['tp'] else '  '}  {r['gt']:7s} ({r['iou']:.2f}) "
              f"{r['room_gt'] or '-':8s} {size:15s} {r['top']:.2f}  {r['side']:.2f}  {r['model'][:20]:20s} {ev}")
    tp_ranks = [i + 1 for i, r in enumerate(rows) if r["tp"]]
    print("true positives at ranks", tp_ranks)
    for k in sorted({max(1, len(tp_ranks) // 2), len(tp_ranks)}):
        above = Counter(kind(r) for r in rows[:tp_ranks[k - 1]] if not r["tp"]) if tp_ranks else Counter()
        print(f"false positives above true positive {k}: {dict(above.most_common())}")
    print("AP25 with one kind of false positive taken out (oracle):")
    for k, v in oracle(rows, npos):
        print(f"  {k:24s} {v:.3f}")
    for expr in args.factor:
        code = compile(expr, "--factor", "eval")

        def key(r, code=code):
            return r["score"] * float(eval(code, {"math": math}, dict(r)))  # noqa: S307 (a local diagnosis aid)
        print(f"AP25 with scores x ({expr}): {ap25(rows, npos, key):.3f}")


if __name__ == "__main__":
    main()
