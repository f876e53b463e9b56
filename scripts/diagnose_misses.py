#!/usr/bin/env python3
"""Where each ground-truth object of one class is lost on its way through a graph with a fit stage.

For every ground-truth object of --cls in the dataset (the points of its scan inside its box are
the object's seen points; the box is axis-aligned, as the evaluation's, so for an object turned far
from the axes it also holds points of its neighbours and the floor, and (a) may then be counted for
an object that was proposed), one cause, the first that applies:
  a  no proposal: no candidate of the recogniser stage (any class; its box is its proposal's box)
     holds >= 50 % of the object's seen points with >= 50 % of the points in that box being the
     object's. With --all-proposals: split into a0 (no such proposal at all) and a1 (there is one,
     but the recogniser's per-class non-maximum suppression dropped it);
  b  box wrong: a proposal of it exists, but no fitted candidate of the final stage (any class,
     accepted or not) overlaps its box by 3D IoU >= 0.25;
  d  another class: fitted candidates overlap it by IoU >= 0.25, none of its class;
  c  outranked: a candidate of its class overlaps it by IoU >= 0.25 but is not a true positive
     at the shipped threshold (scored below it, explained away, or below a false positive of
     the class); 'ok' when it is one.

usage: scripts/diagnose_misses.py --dataset VIEWS/dataset.json --final DIR --proposals DIR [--all-proposals DIR]
       [--cls chair] [--group 'scene(\\d{4})']
DIR: folders of per-scan detections as `furnihost eval --save-detections` writes them
(OUT/detections/<config>/<seed>/): --final of the whole graph, --proposals of the same graph
without its fit stage ({"extends": GRAPH, "stages": {"fit": null}}), --all-proposals of that one
with the recogniser's `nms_iou` at 1.
"""
import argparse
import json
import os
import re
import struct
import sys
from collections import Counter, defaultdict

sys.dont_write_bytecode = True  # no __pycache__ left in scripts/ by the import below
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cross_validate import box_iou, load, match_scene  # noqa: E402


def read_xyz(path):
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii", "replace").splitlines()
    if "format binary_little_endian 1.0" not in header:
        raise SystemExit(f"{path}: expected a binary little-endian PLY")
    kinds = {"float": "f", "uchar": "B", "ushort": "H", "int": "i", "uint": "I", "double": "d", "short": "h",
             "char": "b"}
    n, props = 0, []
    for line in header:
        t = line.split()
        if t[:2] == ["element", "vertex"]:
            n = int(t[2])
        elif t[:1] == ["property"] and len(t) == 3:
            props.append((t[2], kinds[t[1]]))
    fmt = "<" + "".join(k for _, k in props)
    size = struct.calcsize(fmt)
    ix = [p for p, _ in props].index("x")
    return [struct.unpack_from(fmt, data, end + i * size)[ix:ix + 3] for i in range(n)]


def inside(p, box):
    lo, hi = box
    return all(lo[k] <= p[k] <= hi[k] for k in range(3))


def boxes(folder, stem, evaluated):
    path = os.path.join(folder, stem + ".json")
    out = []
    for d in load(path)["detections"]:
        if "box" not in d:
            continue
        a = d["box"]["aabb"]
        out.append({"cls": evaluated(d["class"]), "score": d["score"], "verified": d.get("verified"),
                    "box": (tuple(a["min"]), tuple(a["max"])), "center": d["center"],
                    "rejection": d.get("rejection", "")})
    return out


def scene_causes(pts, gts, final, props, allp, cls):
    """Per ground-truth object of `cls` in one scene: (class, box, centre, cause, best fitted
    candidate by IoU). pts: the scan's points; gts: [(class, (lo, hi), centre, radius)]; final,
    props, allp: candidates as boxes() gives them (allp None: causes a, not a0 / a1)."""
    # True positives of the final stage at its own operating points (verified detections only).
    acc = [d for d in final if d["verified"] and d["cls"] is not None]
    tp = match_scene([(d["score"], d["cls"], d["box"], d["center"]) for d in acc], gts, "iou")
    tp_boxes = [d["box"] for d, t in zip(acc, tp) if t and d["cls"] == cls]

    def proposes(box, own):
        n_in = sum(1 for p in pts if inside(p, box))
        n_both = sum(1 for p in own if inside(p, box))
        return bool(own) and n_both >= 0.5 * len(own) and n_in > 0 and n_both >= 0.5 * n_in

    out = []
    for gc, gbox, gctr, _ in gts:
        if gc != cls:
            continue
        own = [p for p in pts if inside(p, gbox)]
        if not any(proposes(d["box"], own) for d in props):
            cause = "a"
            if allp is not None:
                cause = "a1" if any(proposes(d["box"], own) for d in allp) else "a0"
        else:
            over = [d for d in final if box_iou(d["box"], gbox) >= 0.25]
            if not over:
                cause = "b"
            elif not any(d["cls"] == cls for d in over):
                cause = "d"
            elif any(box_iou(b, gbox) >= 0.25 for b in tp_boxes):
                cause = "ok"
            else:
                cause = "c"
        best = max(final, key=lambda d: box_iou(d["box"], gbox), default=None)
        out.append((gc, gbox, gctr, cause, best))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dataset", required=True)
    ap.add_argument("--final", required=True)
    ap.add_argument("--proposals", required=True)
    ap.add_argument("--all-proposals")
    ap.add_argument("--cls", default="chair")
    ap.add_argument("--group", default=r"scene(\d{4})")
    ap.add_argument("--verbose", "-v", action="store_true")
    a = ap.parse_args()
    m = load(a.dataset)
    base = os.path.dirname(os.path.abspath(a.dataset))
    cmap, classes = m.get("class_map", {}), m["classes"]

    def evaluated(c):
        return cmap.get(c, c if c in classes else None)

    tally = defaultdict(Counter)
    for sc in m["scenes"]:
        stem = os.path.splitext(os.path.basename(sc["scan"]))[0]
        g = re.search(a.group, stem)
        group = g.group(1) if g else stem
        gts = []
        for o in load(os.path.join(base, sc["gt"]))["objects"]:
            c = evaluated(o["class"])
            if c is None:
                continue
            ctr, size = o["center"], o["size"]
            gts.append((c, (tuple(ctr[k] - size[k] / 2 for k in range(3)), tuple(ctr[k] + size[k] / 2 for k in range(3))),
                        ctr, max(size[0], size[1]) / 2))
        if not any(c == a.cls for c, *_ in gts):
            continue
        pts = read_xyz(os.path.join(base, sc["scan"]))
        final = boxes(a.final, stem, evaluated)
        props = boxes(a.proposals, stem, evaluated)
        allp = boxes(a.all_proposals, stem, evaluated) if a.all_proposals else None
        for gc, gbox, gctr, cause, best in scene_causes(pts, gts, final, props, allp, a.cls):
            tally[group][cause] += 1
            if a.verbose:
                bi = box_iou(best["box"], gbox) if best else 0.0
                print(f"{stem} {a.cls} at ({gctr[0]:.2f},{gctr[1]:.2f}): {cause}; best fit "
                      f"{best['cls'] if best else '-'} IoU {bi:.2f} score {best['score'] if best else 0:.4f} "
                      f"{best['rejection'] if best else ''}")
    total = Counter()
    for group in sorted(tally):
        total.update(tally[group])
        print(group, dict(sorted(tally[group].items())))
    print("all", dict(sorted(total.items())))


if __name__ == "__main__":
    main()
