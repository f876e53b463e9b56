#!/usr/bin/env python3
"""Catalog scale: configs/scannet.json trained on the shared catalog grown 10x and 100x, and its
recognition on the ScanNet dev rooms with and without the catalog index, against catalog size.

    benchmarks/catalog/catalog_scale.py [--factors 1,10,100] [--ranks N] [--rooms K] [--out DIR]
                                        [--build DIR] [--no-train] [--seed S]

1. Grows the shared catalog (../shared/data/cad_catalog, 38 models: `furnihost validate --catalog`
   gives each model's class and imported size) into OUT/x<F>/catalog.json, F - 1 variants per
   model: every other variant scaled (one factor on all three axes), the others stretched (a
   factor per axis), each factor drawn in [0.8, 1.25] and the size then kept within the real size
   range of the model's class (the smallest and largest extent of the class's catalog models per
   axis, widened by 10 %); the variants use the model's own mesh (a per-axis size_m), so the
   grown catalog references the shared meshes in place. x1 is the shared catalog itself.
2. Trains configs/scannet.json on each (a derived graph in OUT/x<F>/ that only changes the catalog
   and the model cache): wall and CPU time (user + system, all threads and ranks) and peak
   resident memory from the process's rusage, and the model file's size. --ranks N trains with
   `mpirun -n N` (one thread a rank; docs/cluster.md).
3. Runs `furnihost eval` of benchmarks/scannet_dev.json (the first --rooms rooms, default all 18)
   with each model, the catalog index on (the default) and off (--set recognise.index=false), one
   scene at a time (--jobs 1): the recognition stage's time per room, the models scored per
   proposal and class (voters.catalog_shape's debug line), the model's load time, and AP25 per
   class (on and off must agree: the index finds the same best model as scoring every model).
4. Prints the growth table and writes OUT/catalog_scale.md and .json, with the load average.

Training at 100x simulates 16 views of 3,800 models: about an hour of CPU on 2 cores.
"""
import argparse
import json
import os
import random
import re
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CONFIG = "configs/scannet.json"


def run(cmd, **kw):
    """(wall s, CPU s of the process and its children, peak RSS MB, stdout, stderr)."""
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, **kw)
    out, err = p.communicate()
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise SystemExit(f"catalog_scale.py: {' '.join(cmd)} failed ({p.returncode}):\n{err.decode()[-3000:]}")
    return wall, out.decode(), err.decode()


def rusage_run(cmd, env=None):
    """Runs cmd and returns (wall s, CPU s, peak RSS MB) from wait4."""
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    err = p.stderr.read().decode(errors="replace")
    _, status, ru = os.wait4(p.pid, 0)
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"catalog_scale.py: {' '.join(cmd)} failed:\n{err[-3000:]}")
    return time.perf_counter() - t0, ru.ru_utime + ru.ru_stime, ru.ru_maxrss / 1024.0


def grow(fh, out, factor, seed):
    """Writes OUT/x<factor>/catalog.json and the derived graph; returns the graph's path."""
    folder = os.path.join(out, f"x{factor}")
    os.makedirs(folder, exist_ok=True)
    _, listed, _ = run([fh, "validate", "--graph", CONFIG, "--catalog", "-q"])
    listing = json.loads(listed[listed.index("{"):])
    source = listing["catalog"]
    with open(source) as f:
        shared = json.load(f)
    entries = {m["id"]: m for m in shared["models"]}
    models = listing["models"]
    # Each class's real size range: its catalog models' extents per axis, widened by 10 %.
    ranges = {}
    for m in models:
        lo, hi = ranges.setdefault(m["class"], ([1e9] * 3, [0.0] * 3))
        for a in range(3):
            lo[a], hi[a] = min(lo[a], m["size"][a]), max(hi[a], m["size"][a])
    ranges = {c: ([0.9 * x for x in lo], [1.1 * x for x in hi]) for c, (lo, hi) in ranges.items()}
    rng = random.Random(seed)
    grown = []
    base = os.path.dirname(source)
    for m in models:
        e = dict(entries[m["id"]])
        e["mesh"] = os.path.relpath(os.path.join(base, e["mesh"]), os.path.abspath(folder))
        grown.append(e)
        lo, hi = ranges[m["class"]]
        for v in range(1, factor):
            s = rng.uniform(0.8, 1.25)
            f = [s] * 3 if v % 2 else [rng.uniform(0.8, 1.25) for _ in range(3)]
            size = [round(min(max(m["size"][a] * f[a], lo[a]), hi[a]), 4) for a in range(3)]
            var = {k: x for k, x in e.items() if k not in ("scale", "height_m", "size_m")}
            var["id"] = f"{m['id']}_v{v:03d}"
            var["size_m"] = size
            var["source"] = f"{m['id']} {'scaled' if v % 2 else 'stretched'} to {size} (benchmarks/catalog/catalog_scale.py)"
            grown.append(var)
    with open(os.path.join(folder, "catalog.json"), "w") as f:
        json.dump({"furnihost_catalog": 1, "description": f"the shared catalog grown {factor}x", "models": grown}, f, indent=1)
    graph = os.path.join(folder, "scannet.json")
    with open(graph, "w") as f:
        json.dump({"extends": os.path.relpath(os.path.join(ROOT, CONFIG), os.path.abspath(folder)),
                   "catalog": "catalog.json", "model_cache": "model.fhm"}, f)
    return graph, len(grown)


def dataset(out, rooms):
    """benchmarks/scannet_dev.json, its first `rooms` rooms, paths made absolute."""
    path = os.path.join(ROOT, "benchmarks", "scannet_dev.json")
    with open(path) as f:
        d = json.load(f)
    d["scenes"] = d["scenes"][:rooms]
    for s in d["scenes"]:
        for k in ("scan", "gt"):
            s[k] = os.path.abspath(os.path.join(os.path.dirname(path), s[k]))
    dst = os.path.join(out, f"scannet_dev_{rooms}.json")
    with open(dst, "w") as f:
        json.dump(d, f)
    return dst


def recognise(fh, graph, data, out, index):
    cmd = [fh, "eval", "--graph", graph, "--dataset", data, "--out", out, "--jobs", "1", "--threads", "2", "-vv"]
    if not index:
        cmd += ["--set", "recognise.index=false"]
    wall, _, err = run(cmd)
    with open(os.path.join(out, "summary.json")) as f:
        summary = json.load(f)
    r = summary["configs"][0]["runs"][0]
    n = len(r["scenes"])
    stage = dict((t["stage"], t["ms"]) if isinstance(t, dict) else tuple(t) for t in r["stage_ms"]) \
        if isinstance(r["stage_ms"], list) else r["stage_ms"]
    per, models = [], []
    for line in err.splitlines():
        m = re.search(r"catalog_shape: (\d+) models scored for (\d+) proposal-class pairs: ([0-9.]+) per pair of the ([0-9.]+)", line)
        if m:
            per.append(float(m.group(3)))
            models.append(float(m.group(4)))
    ap25 = {c["class"]: c.get("ap25") for c in r["metrics"]["classes"]}
    return {"recognise_ms_per_room": stage.get("recognise", 0.0) / max(n, 1), "model_ms": r["model_ms"], "wall_s": wall,
            "scored_per_pair": sum(per) / max(len(per), 1), "class_models_per_pair": sum(models) / max(len(models), 1),
            "ap25": ap25, "rooms": n}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--factors", default="1,10,100")
    ap.add_argument("--ranks", type=int, default=1)
    ap.add_argument("--rooms", type=int, default=18)
    ap.add_argument("--out", default="runs/catalog_scale")
    ap.add_argument("--build", default="build")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--no-train", action="store_true", help="use each grown catalog's cached model (trains if stale)")
    args = ap.parse_args()
    fh = os.path.join(args.build, "bin", "furnihost")
    os.makedirs(args.out, exist_ok=True)
    data = dataset(args.out, args.rooms)
    load = [os.getloadavg()]
    rows = []
    for factor in [int(x) for x in args.factors.split(",")]:
        graph, models = grow(fh, args.out, factor, args.seed)
        row = {"factor": factor, "models": models}
        if not args.no_train:
            cmd = [fh, "train", "--graph", graph, "-q"]
            env = dict(os.environ)
            if args.ranks > 1:
                cmd = ["mpirun", "--oversubscribe", "-n", str(args.ranks)] + cmd + ["--threads", "1"]
                env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
            else:
                cmd += ["--threads", "2"]
            wall, cpu, rss = rusage_run(cmd, env)
            row.update(train_wall_s=wall, train_cpu_s=cpu, train_peak_rss_mb=rss)
            print(f"catalog_scale: x{factor} ({models} models) trained in {wall:.0f} s, {cpu:.0f} s CPU, {rss:.0f} MB",
                  file=sys.stderr)
        model = os.path.join(os.path.dirname(graph), "model.fhm")
        row["model_mb"] = os.path.getsize(model) / 1e6 if os.path.exists(model) else None
        for index in (True, False):
            key = "index_on" if index else "index_off"
            row[key] = recognise(fh, graph, data, os.path.join(args.out, f"x{factor}", key), index)
            print(f"catalog_scale: x{factor} index {'on' if index else 'off'}: "
                  f"{row[key]['recognise_ms_per_room']:.0f} ms per room, {row[key]['scored_per_pair']:.1f} models scored "
                  f"of {row[key]['class_models_per_pair']:.0f}", file=sys.stderr)
        rows.append(row)
    load.append(os.getloadavg())
    md = [f"## configs/scannet.json against catalog size ({args.rooms} ScanNet dev rooms; training "
          f"{'on ' + str(args.ranks) + ' MPI ranks' if args.ranks > 1 else 'one process, 2 threads'})", "",
          "load average (1, 5, 15 min) before and after: " + "; ".join(", ".join(f"{x:.1f}" for x in l) for l in load), "",
          "| models | train wall [s] | train CPU [s] | CPU per model [s] | peak RSS [MB] | model file [MB] | model load [ms] | "
          "recognition per room [ms], index on / off | models scored per proposal and class, on / off | AP25 equal |",
          "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        on, off = r["index_on"], r["index_off"]
        same = on["ap25"] == off["ap25"]
        md.append("| " + " | ".join([
            str(r["models"]),
            f"{r.get('train_wall_s', float('nan')):.0f}", f"{r.get('train_cpu_s', float('nan')):.0f}",
            f"{r.get('train_cpu_s', float('nan')) / r['models']:.3f}", f"{r.get('train_peak_rss_mb', float('nan')):.0f}",
            f"{r['model_mb']:.1f}" if r["model_mb"] else "-", f"{on['model_ms']:.0f}",
            f"{on['recognise_ms_per_room']:.0f} / {off['recognise_ms_per_room']:.0f}",
            f"{on['scored_per_pair']:.1f} / {off['scored_per_pair']:.1f}", "yes" if same else "NO"]) + " |")
    md += ["", "AP25 per class (index on): " + "; ".join(
        f"{r['models']} models: " + ", ".join(f"{c} {v:.3f}" for c, v in r["index_on"]["ap25"].items() if v is not None)
        for r in rows)]
    text = "\n".join(md) + "\n"
    print(text)
    with open(os.path.join(args.out, "catalog_scale.md"), "w") as f:
        f.write(text)
    with open(os.path.join(args.out, "catalog_scale.json"), "w") as f:
        json.dump({"load": load, "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
