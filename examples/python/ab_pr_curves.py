#!/usr/bin/env python3
"""Evaluate two configs A and B on a dataset and plot their precision-recall curves.

    python3 examples/python/ab_pr_curves.py [--a CONFIG] [--b CONFIG] [--b-set TAG.PARAM=VALUE ...]
                                            [--dataset benchmarks/scannet_dev.json] [--out DIR]

By default A is configs/scannet.json and B the same graph without the recogniser's floor term
(--b-set recognise.floor_term=false): an A/B that differs in one thing. Writes DIR/pr_curves.png
(recall against 1 - precision per class, box IoU >= 0.25, AP25 in the legend) and
DIR/summary_A.json / summary_B.json (what `furnihost eval` writes as summary.json).
"""
import argparse
import json
import os
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

import furnihost

ROOT = pathlib.Path(__file__).resolve().parents[2]


def parse_set(items):
    out = {}
    for item in items:
        key, _, value = item.partition("=")
        out[key] = json.loads(value)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--a", default=ROOT / "configs" / "scannet.json")
    ap.add_argument("--b", default=None, help="default: the same config as A")
    ap.add_argument("--b-set", action="append", default=None, help="TAG.PARAM=VALUE for B (default: "
                    "recognise.floor_term=false)")
    ap.add_argument("--dataset", default=ROOT / "benchmarks" / "scannet_dev.json")
    ap.add_argument("--out", default="furnihost-out/python_ab")
    args = ap.parse_args()
    b_set = parse_set(args.b_set if args.b_set is not None else ["recognise.floor_term=false"])
    os.makedirs(args.out, exist_ok=True)

    runs = {
        "A": furnihost.Graph(args.a).evaluate(args.dataset, name="A"),
        "B": furnihost.Graph(args.b or args.a, set=b_set).evaluate(args.dataset, name="B"),
    }
    for label, summary in runs.items():
        with open(os.path.join(args.out, f"summary_{label}.json"), "w") as f:
            json.dump(summary, f, indent=1)

    classes = [c["class"] for c in runs["A"]["configs"][0]["runs"][0]["metrics"]["classes"]]
    fig, axes = plt.subplots(1, len(classes), figsize=(4 * len(classes), 4), squeeze=False)
    for ax, cls in zip(axes[0], classes):
        for label, style in (("A", "-"), ("B", "--")):
            metrics = runs[label]["configs"][0]["runs"][0]["metrics"]
            c = next(c for c in metrics["classes"] if c["class"] == cls)
            rows = c["pr_curve_iou25"]  # [score, tp, fp, precision, recall] per score, descending
            x = [1.0 - r[3] for r in rows if r[3] is not None]
            y = [r[4] for r in rows if r[3] is not None]
            ap25 = "n/a" if c["ap25"] is None else f"{c['ap25']:.3f}"
            ax.plot(x, y, style, label=f"{label}: AP25 {ap25}")
            print(f"{cls:8s} {label}: AP25 {ap25} ({c['gt']} objects, {c['detections']} detections)")
        ax.set_title(cls)
        ax.set_xlabel("1 - precision")
        ax.set_xlim(0, 1)
        ax.set_ylim(0, 1.02)
        ax.legend(loc="lower right")
    axes[0][0].set_ylabel("recall")
    fig.suptitle(f"{pathlib.Path(args.dataset).name}: A = {pathlib.Path(args.a).name}, "
                 f"B = {pathlib.Path(args.b or args.a).name} {b_set}")
    picture = os.path.join(args.out, "pr_curves.png")
    fig.savefig(picture, dpi=110, bbox_inches="tight")
    print(f"-> {picture}")


if __name__ == "__main__":
    main()
