#!/usr/bin/env python3
"""Trains a graph with several training seeds and evaluates each model on a dataset: how far its
figures move with the draw of the training (simulated training views' noise, the k-means draw of
the vocabulary).

For each seed S it writes WORK/seed<S>.json, a config that extends the graph with `"seed": S`
and its own `model_cache` (WORK/seed<S>.fhm), runs `furnihost eval` on it into WORK/eval<S>/
and reads the per-class AP from its summary.json. The detections use one fixed seed
(--detection-seed, default the graph's), so only the training differs between the runs; pass
`--detection-seed same` to detect with each training seed as well (what a user of a config with
that seed gets).

Prints per evaluated class the mean, sample standard deviation, min and max over the seeds of
AP25 and of the paper's AP (centre within half the object's width, Sect. VII-A), and the mAP;
--out writes the same as JSON, with every seed's figures.

usage: scripts/training_seeds.py --graph configs/paper.json --dataset benchmarks/synthetic.json \\
           [--seeds 5] [--seed0 42] [--work /tmp/training_seeds] [--set vote.restarts=30] [--out seeds.json]
Existing model caches in WORK are reused (the cache is keyed by the resolved config, so a
changed config retrains); --set values go into each seed's config as stage parameters.
"""
import argparse
import json
import math
import os
import subprocess
import sys


def load(path):
    with open(path) as f:
        return json.load(f)


def stats(values):
    """Mean, sample standard deviation (0 for one value), min and max of the finite values."""
    v = [x for x in values if x is not None and math.isfinite(x)]
    if not v:
        return {"mean": None, "std": None, "min": None, "max": None, "n": 0}
    m = sum(v) / len(v)
    sd = math.sqrt(sum((x - m) ** 2 for x in v) / (len(v) - 1)) if len(v) > 1 else 0.0
    return {"mean": m, "std": sd, "min": min(v), "max": max(v), "n": len(v)}


def parse_set(items):
    """TAG.PARAM=VALUE (VALUE parsed as JSON when it is JSON, else kept as a string) -> stages patch."""
    stages = {}
    for item in items:
        key, sep, value = item.partition("=")
        tag, dot, param = key.partition(".")
        if not sep or not dot or not tag or not param:
            sys.exit(f"training_seeds: --set expects TAG.PARAM=VALUE, got '{item}'")
        try:
            parsed = json.loads(value)
        except json.JSONDecodeError:
            parsed = value
        stages.setdefault(tag, {}).setdefault("params", {})[param] = parsed
    return stages


def fmt(x):
    return "   -  " if x is None else f"{x:6.3f}"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--graph", required=True)
    ap.add_argument("--dataset", required=True)
    ap.add_argument("--seeds", type=int, default=5, help="number of training seeds (default 5)")
    ap.add_argument("--seed0", type=int, default=None, help="first training seed (default: the graph's)")
    ap.add_argument("--detection-seed", default=None,
                    help="seed of the detections: a number, or 'same' for each training seed (default: the graph's)")
    ap.add_argument("--set", action="append", default=[], metavar="TAG.PARAM=VALUE",
                    help="a stage parameter set in every seed's config (repeatable)")
    ap.add_argument("--work", default="/tmp/training_seeds", help="folder of the configs, model caches and evals")
    ap.add_argument("--furnihost", default="build/bin/furnihost")
    ap.add_argument("--out", help="write the figures as JSON here")
    args = ap.parse_args()
    if args.seeds < 1:
        sys.exit("training_seeds: --seeds must be positive")

    graph = os.path.abspath(args.graph)
    dataset = os.path.abspath(args.dataset)
    base_seed = load(graph).get("seed", 42)
    seed0 = base_seed if args.seed0 is None else args.seed0
    os.makedirs(args.work, exist_ok=True)
    patch = parse_set(args.set)
    classes = load(dataset)["classes"]

    runs = []
    for seed in range(seed0, seed0 + args.seeds):
        cfg_path = os.path.join(args.work, f"seed{seed}.json")
        cfg = {"extends": graph, "seed": seed, "model_cache": os.path.abspath(os.path.join(args.work, f"seed{seed}.fhm"))}
        if patch:
            cfg["stages"] = patch
        with open(cfg_path, "w") as f:
            json.dump(cfg, f, indent=2)
        det_seed = seed if args.detection_seed == "same" else (
            base_seed if args.detection_seed is None else int(args.detection_seed))
        out_dir = os.path.join(args.work, f"eval{seed}")
        cmd = [args.furnihost, "eval", "--graph", cfg_path, "--dataset", dataset, "--out", out_dir,
               "--seed", str(det_seed), "-q"]
        print(f"training seed {seed}: {' '.join(cmd)}", file=sys.stderr, flush=True)
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        summary = load(os.path.join(out_dir, "summary.json"))
        run = summary["configs"][0]["runs"][0]
        per_class = {m["class"]: m for m in run["metrics"]["classes"]}
        runs.append({"training_seed": seed, "detection_seed": det_seed,
                     "classes": {c: {"ap25": per_class.get(c, {}).get("ap25"), "ap": per_class.get(c, {}).get("ap"),
                                     "gt": per_class.get(c, {}).get("gt")} for c in classes}})

    figures = {}
    for c in classes:
        figures[c] = {key: stats([r["classes"][c][key] for r in runs]) for key in ("ap25", "ap")}
    for r in runs:
        r["mAP"] = {}
        for key in ("ap25", "ap"):
            v = [r["classes"][c][key] for c in classes if r["classes"][c][key] is not None]
            r["mAP"][key] = sum(v) / len(v) if v else None
    figures["mAP"] = {key: stats([r["mAP"][key] for r in runs]) for key in ("ap25", "ap")}

    print(f"{args.graph} on {args.dataset}: training seeds {seed0}..{seed0 + args.seeds - 1}"
          f"{' with ' + ' '.join(args.set) if args.set else ''}")
    print(f"{'':8s} {'':5s} {'mean':>6s} {'std':>6s} {'min':>6s} {'max':>6s}   per seed")
    for c in classes + ["mAP"]:
        for key in ("ap25", "ap"):
            s = figures[c][key]
            seeds_txt = " ".join(fmt(r["mAP"][key] if c == "mAP" else r["classes"][c][key]) for r in runs)
            print(f"{c:8s} {key:5s} {fmt(s['mean'])} {fmt(s['std'])} {fmt(s['min'])} {fmt(s['max'])}   {seeds_txt}")
    if args.out:
        with open(args.out, "w") as f:
            json.dump({"graph": args.graph, "dataset": args.dataset, "set": args.set,
                       "training_seeds": [r["training_seed"] for r in runs], "figures": figures, "runs": runs},
                      f, indent=2)
            f.write("\n")


if __name__ == "__main__":
    main()
