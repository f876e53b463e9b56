#!/usr/bin/env python3
"""Catalog scale: training and recognition cost against the number of catalog models, in one command.

    benchmarks/speed/catalog_scale.py [--quick] [--factors 1,10,100] [--graph configs/scannet.json]
                                      [--rooms N] [--threads N] [--seed S] [--build DIR] [--out DIR]
                                      [--dry-run]

1. Reads the shared catalog ($FURNIHOST_SHARED_DATA_DIR/cad_catalog/catalog.json, default
   ../shared/data) and measures each model's size in metres as the host loads it (`furnihost
   simulate` places every model once, unturned, in a long empty room; its ground truth gives the
   extents [width, depth, height] after the entry's "up" and "scale" / "height_m" / "size_m").
2. Writes one grown catalog per factor F under OUT/catalogs/: the shared models as they are plus
   F - 1 variants of each. A variant names the same mesh file (absolute path, never copied), the
   same "up", class and subclass, and a "size_m" [width, depth, height]: the model's size times a
   uniform scale (0.8 .. 1.25) times a stretch per axis (0.85 .. 1.18), drawn from a seeded RNG
   until it lies in its class's real size range (per axis, the min .. max of that class's models
   in the shared catalog, widened by 10 %), else clipped into it. "size_m" fits the mesh's box
   per axis, so a stretch is what the catalog itself expresses.
3. Per factor: a graph OUT/configs/xF.json that `extends` --graph (default configs/scannet.json)
   with the grown catalog and a model cache OUT/models/xF.fhm; times `furnihost train --graph`
   as a whole process (wall, user + system CPU of all threads, peak resident memory: wait4's
   rusage) and reads the model file's size; then `furnihost eval --graph --dataset
   benchmarks/scannet_dev.json --jobs 1` (the first --rooms scenes; default all 18) reads from
   its summary.json the median time per room, the voter stage's median per room, the time to
   load the model, the eval's peak memory, mAP25 and AP25 per class.
4. Prints and writes OUT/catalog_scale.md (the table, the log-log slopes of training CPU time and
   of recognition time per room against the number of models, AP25 per class), OUT/catalog_scale.json
   (every measurement) and OUT/catalog_scale.svg (times against models, log-log).

--quick: factors 1,3,10 on 4 rooms. --dry-run: writes the catalogs and configs and prints the
commands it would time, without running them (after the one `furnihost simulate` that sizes the
models). --keep: the factors already in OUT/catalog_scale.json are not measured again (a larger
factor added to an earlier run). Run it under `nice` on a shared machine; CPU times move less with the load than wall times.
"""
import argparse
import json
import math
import os
import random
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
import report  # noqa: E402  (svg_plot)

SCALE = (0.8, 1.25)      # uniform scale of a variant
STRETCH = (0.85, 1.18)   # factor per axis on top of it
WIDEN = 1.10             # a class's size range, widened by 10 % each way
TRIES = 50               # draws before a variant is clipped into its class's range


def run(cmd, log=None):
    """Runs cmd in the project root; returns (wall s, user + system CPU s, peak RSS MB, return code)."""
    t0 = time.perf_counter()
    with open(log, "w") if log else open(os.devnull, "w") as out:
        p = subprocess.Popen(cmd, cwd=ROOT, stdout=out, stderr=subprocess.STDOUT)
        _, status, ru = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    return wall, ru.ru_utime + ru.ru_stime, ru.ru_maxrss / 1024.0, os.waitstatus_to_exitcode(status)


def model_sizes(fh, catalog, work):
    """{id: [width, depth, height] m} of every model, as the host loads it (one simulated room)."""
    models = json.load(open(catalog))["models"]
    spacing = 4.0  # wider than any model's diagonal in the shared catalog (< 3 m)
    scene = {"room": {"size_m": [spacing * len(models) + spacing, 6.0], "height_m": 3.0, "walls": False,
                      "ceiling": False},
             "objects": [{"model": m["id"], "x": spacing * (k + 1), "y": 3.0, "yaw_deg": 0}
                         for k, m in enumerate(models)],
             "sensors": [{"position": [1.0, 0.5, 1.5], "yaw_deg": 0, "pitch_deg": 0}],
             "sensor_params": {"voxel_m": 0.1}}
    os.makedirs(work, exist_ok=True)
    path = os.path.join(work, "sizes.scene.json")
    json.dump(scene, open(path, "w"))
    cmd = [fh, "simulate", "--catalog", catalog, "--scene", path, "--out", os.path.join(work, "sizes.pcd"), "-q"]
    if subprocess.run(cmd, cwd=ROOT).returncode != 0:
        sys.exit("catalog_scale: " + " ".join(cmd) + " failed")
    gt = json.load(open(os.path.join(work, "sizes.gt.json")))
    sizes = {o["model"]: o["size"] for o in gt["objects"]}
    missing = [m["id"] for m in models if m["id"] not in sizes]
    if missing:
        sys.exit("catalog_scale: no size for " + ", ".join(missing))
    return sizes


def grow(catalog, sizes, factor, seed):
    """The shared catalog plus factor - 1 scaled and stretched variants of each model."""
    src = json.load(open(catalog))
    base = os.path.dirname(os.path.abspath(catalog))
    lo, hi = {}, {}
    for m in src["models"]:
        c, s = m["class"], sizes[m["id"]]
        lo[c] = [min(a, b) for a, b in zip(lo.get(c, s), s)]
        hi[c] = [max(a, b) for a, b in zip(hi.get(c, s), s)]
    rng = random.Random(seed)
    models = []
    for m in src["models"]:
        e = dict(m)
        e["mesh"] = os.path.normpath(os.path.join(base, m["mesh"]))
        models.append(e)
    for k in range(1, factor):
        for m in src["models"]:
            c, s = m["class"], sizes[m["id"]]
            rlo, rhi = [v / WIDEN for v in lo[c]], [v * WIDEN for v in hi[c]]
            for _ in range(TRIES):
                u = rng.uniform(*SCALE)
                size = [v * u * rng.uniform(*STRETCH) for v in s]
                if all(a <= v <= b for v, a, b in zip(size, rlo, rhi)):
                    break
            else:
                size = [min(max(v, a), b) for v, a, b in zip(size, rlo, rhi)]
            e = {key: m[key] for key in ("class", "subclass", "up", "front") if key in m}
            e["id"] = f"{m['id']}_v{k}"
            e["mesh"] = os.path.normpath(os.path.join(base, m["mesh"]))
            e["size_m"] = [round(v, 4) for v in size]
            e["notes"] = f"catalog_scale variant {k} of {m['id']}"
            models.append(e)
    return {"furnihost_catalog": 1,
            "frame": src.get("frame", ""),
            "description": f"{len(src['models'])} models of {catalog} and {factor - 1} scaled and stretched variants "
                           f"of each (benchmarks/speed/catalog_scale.py, seed {seed}), meshes read in place",
            "models": models}


def median(v):
    v = sorted(v)
    return 0.5 * (v[(len(v) - 1) // 2] + v[len(v) // 2]) if v else float("nan")


def slope(pts):
    """Least-squares slope of log y against log x."""
    pts = [(math.log(x), math.log(y)) for x, y in pts if x > 0 and y > 0]
    if len(pts) < 2:
        return float("nan")
    mx = sum(x for x, _ in pts) / len(pts)
    my = sum(y for _, y in pts) / len(pts)
    sxx = sum((x - mx) ** 2 for x, _ in pts)
    return sum((x - mx) * (y - my) for x, y in pts) / sxx if sxx > 0 else float("nan")


def fmt(v, f="{:.2f}"):
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else f.format(v)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--factors", default=None, help="catalog sizes as multiples of the shared one (default 1,10,100)")
    ap.add_argument("--quick", action="store_true", help="factors 1,3,10 on 4 rooms")
    ap.add_argument("--graph", default="configs/scannet.json")
    ap.add_argument("--dataset", default="benchmarks/scannet_dev.json")
    ap.add_argument("--rooms", type=int, default=0, help="the first N scenes of the dataset (0 = all)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--build", default="build")
    ap.add_argument("--out", default="runs/catalog_scale")
    ap.add_argument("--keep", action="store_true",
                    help="reuse the rows of OUT/catalog_scale.json for the factors it holds (add a factor to a run)")
    ap.add_argument("--dry-run", action="store_true", help="write catalogs and configs, print the commands, time nothing")
    a = ap.parse_args()
    factors = [int(f) for f in (a.factors or ("1,3,10" if a.quick else "1,10,100")).split(",")]
    rooms = a.rooms or (4 if a.quick else 0)
    os.chdir(ROOT)
    shared = os.environ.get("FURNIHOST_SHARED_DATA_DIR", os.path.join(ROOT, "..", "shared", "data"))
    catalog = os.path.abspath(os.path.join(shared, "cad_catalog", "catalog.json"))
    fh = os.path.join(a.build, "bin", "furnihost")
    out = os.path.abspath(a.out)
    for sub in ("catalogs", "configs", "models", "eval", "logs"):
        os.makedirs(os.path.join(out, sub), exist_ok=True)

    # The dataset with absolute paths (its own are relative to its file), cut to --rooms scenes.
    ds = json.load(open(a.dataset))
    dsdir = os.path.dirname(os.path.abspath(a.dataset))
    for s in ds["scenes"]:
        for k in ("scan", "gt"):
            if k in s and not os.path.isabs(s[k]):
                s[k] = os.path.normpath(os.path.join(dsdir, s[k]))
    if rooms:
        ds["scenes"] = ds["scenes"][:rooms]
    dataset = os.path.join(out, "dataset.json")
    json.dump(ds, open(dataset, "w"), indent=1)

    sizes = model_sizes(fh, catalog, os.path.join(out, "sizes"))
    plan = []
    for f in factors:
        cat = os.path.join(out, "catalogs", f"x{f}.json")
        json.dump(grow(catalog, sizes, f, a.seed + f), open(cat, "w"), indent=1)
        graph = os.path.join(out, "configs", f"x{f}.json")
        json.dump({"extends": os.path.abspath(a.graph), "catalog": cat,
                   "model_cache": os.path.join(out, "models", f"x{f}.fhm")}, open(graph, "w"), indent=1)
        train = [fh, "train", "--graph", graph, "--threads", str(a.threads)]
        ev = [fh, "eval", "--graph", graph, "--dataset", dataset, "--out", os.path.join(out, "eval", f"x{f}"),
              "--jobs", "1", "--threads", str(a.threads), "-q"]
        plan.append((f, len(json.load(open(cat))["models"]), graph, train, ev))
    if a.dry_run:
        for f, n, _, train, ev in plan:
            print(f"x{f}: {n} models\n  " + " ".join(train) + "\n  " + " ".join(ev))
        return

    rows = []
    kept = os.path.join(out, "catalog_scale.json")
    if a.keep and os.path.exists(kept):
        rows = [r for r in json.load(open(kept)) if r["factor"] in factors]
    for f, n, graph, train, ev in plan:
        if any(r["factor"] == f for r in rows):
            continue
        tw, tc, trss, rc = run(train, os.path.join(out, "logs", f"train_x{f}.log"))
        if rc != 0:
            sys.exit(f"catalog_scale: training x{f} failed, see {out}/logs/train_x{f}.log")
        mb = os.path.getsize(os.path.join(out, "models", f"x{f}.fhm")) / 1e6
        ew, ec, erss, rc = run(ev, os.path.join(out, "logs", f"eval_x{f}.log"))
        if rc != 0:
            sys.exit(f"catalog_scale: eval x{f} failed, see {out}/logs/eval_x{f}.log")
        r = json.load(open(os.path.join(out, "eval", f"x{f}", "summary.json")))["configs"][0]["runs"][0]
        per_room = [s["total_ms"] for s in r["scenes"]]
        voter = [sum(t["ms"] for t in s["timings_ms"] if t["stage"] == "recognise") for s in r["scenes"]]
        m = r["metrics"]
        row = {"factor": f, "models": n, "train_wall_s": tw, "train_cpu_s": tc, "train_peak_mb": trss,
               "model_mb": mb, "rooms": len(per_room), "room_ms": median(per_room), "voter_ms": median(voter),
               "model_load_ms": r.get("model_ms"), "model_source": r.get("model_source"), "eval_peak_mb": r.get("peak_rss_mb"), "eval_wall_s": ew,
               "eval_cpu_s": ec, "map25": m.get("map25"),
               "ap25": {c["class"]: c.get("ap25") for c in m.get("classes", [])}}
        if row["model_source"] != "cache":
            # The eval found the trained model stale (the build changed between train and eval, say):
            # its model load is a training then.
            print(f"catalog_scale: warning: eval x{f} did not read the model train wrote ({row['model_source']}); "
                  "its model load time includes training", file=sys.stderr)
        rows.append(row)
        rows.sort(key=lambda r: r["models"])
        print(f"x{f}: {n} models, train {tw:.1f} s wall {tc:.1f} s CPU, model {mb:.1f} MB, "
              f"{row['room_ms']:.0f} ms per room (voter {row['voter_ms']:.0f}), mAP25 {fmt(row['map25'], '{:.3f}')}",
              flush=True)
        json.dump(rows, open(os.path.join(out, "catalog_scale.json"), "w"), indent=1)

    classes = sorted({c for r in rows for c in r["ap25"]})
    lines = ["| models | train wall s | train CPU s | CPU/wall | CPU s per model | model MB | train peak MB | "
             "model load ms | eval peak MB | ms per room | voter ms per room | eval CPU ms per room | mAP25 |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['models']} | {r['train_wall_s']:.1f} | {r['train_cpu_s']:.1f} | "
                     f"{r['train_cpu_s'] / r['train_wall_s']:.2f} | {r['train_cpu_s'] / r['models']:.3f} | "
                     f"{r['model_mb']:.3f} | {r['train_peak_mb']:.0f} | {fmt(r['model_load_ms'], '{:.0f}')}"
                     f"{'' if r.get('model_source', 'cache') == 'cache' else ' (retrained)'} | "
                     f"{fmt(r['eval_peak_mb'], '{:.0f}')} | {r['room_ms']:.0f} | {r['voter_ms']:.1f} | "
                     f"{1000 * r['eval_cpu_s'] / r['rooms']:.0f} | "
                     f"{fmt(r['map25'], '{:.3f}')} |")
    lines += ["", "| models | " + " | ".join(f"AP25 {c}" for c in classes) + " |",
              "|---:|" + "---:|" * len(classes)]
    for r in rows:
        lines.append(f"| {r['models']} | " + " | ".join(fmt(r["ap25"].get(c), "{:.3f}") for c in classes) + " |")
    s = {k: slope([(r["models"], r[k]) for r in rows])
         for k in ("train_wall_s", "train_cpu_s", "model_mb", "room_ms", "voter_ms", "eval_cpu_s")}
    lines += ["", "Log-log slope against the number of models (1 = linear, 0 = flat): training CPU "
              f"{fmt(s['train_cpu_s'])}, training wall {fmt(s['train_wall_s'])}, model file {fmt(s['model_mb'])}, "
              f"recognition per room {fmt(s['room_ms'])}, voter stage per room {fmt(s['voter_ms'])}, eval CPU "
              f"{fmt(s['eval_cpu_s'])}."]
    when = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    load = os.getloadavg()[0]
    head = [f"# Catalog scale: {a.graph} on {rows[0]['rooms']} rooms of {a.dataset}", "",
            f"Written by benchmarks/speed/catalog_scale.py on {when}, {os.cpu_count()} cores, load average "
            f"{load:.1f} at the end, --threads {a.threads}, eval --jobs 1. Per room: the median over the rooms of "
            "the scene's time (input, ground, propose, recognise) and of the voter stage (recognise); "
            "model load is reading the model file once per eval; eval CPU per room is the eval process's user + "
            "system time (all threads, model load included) over the rooms, which a loaded machine moves less "
            "than the wall times.", ""]
    text = "\n".join(head + lines) + "\n"
    print(text)
    with open(os.path.join(out, "catalog_scale.md"), "w") as fh_:
        fh_.write(text)
    report.svg_plot([("train CPU", "#d62728", [(r["models"], r["train_cpu_s"]) for r in rows]),
                     ("train wall", "#ff9896", [(r["models"], r["train_wall_s"]) for r in rows]),
                     ("room", "#1f77b4", [(r["models"], r["room_ms"] / 1000) for r in rows]),
                     ("voter / room", "#2ca02c", [(r["models"], r["voter_ms"] / 1000) for r in rows])],
                    os.path.join(out, "catalog_scale.svg"), "Cost against catalog size",
                    xlabel="catalog models", ylabel="time [s]")
    print(f"wrote {out}/catalog_scale.md, catalog_scale.json, catalog_scale.svg")


if __name__ == "__main__":
    main()
