#!/usr/bin/env python3
"""Dense laser scans: configs/paper.json end to end from 0.1M to 4M points, and our segmentation +
features against PCL NormalEstimationOMP + RegionGrowing on the same clouds, in one command.

    benchmarks/speed/dense.py [--quick] [--runs N] [--build DIR] [--out DIR] [--no-build]
                              [--baseline DIR] [--no-pcl]

1. Builds furnihost and bench_region_growing (-DFURNIHOST_BUILD_BENCH=ON) in --build (default
   build/), unless --no-build.
2. Simulates (once; kept in OUT/rooms/) the demo room (data/demo/room.scene.json, its 360 deg
   pan-tilt scanner, no voxel filter) at angular steps giving ~0.1M, 0.25M, 0.5M, 1.0M, 2M, 3.7M and
   4.1M points, and a held-out-style office (benchmarks/speed/office.scene.json: models of
   data/demo/catalog.json, none in the training catalog, scanned off-centre) at ~1.0M.
3. Runs `furnihost --graph configs/paper.json ROOM --threads 2 --out ...` as whole processes,
   --runs times per room (default 3), the rooms interleaved run by run (a burst of load on a
   shared machine then spreads over the rooms instead of hitting one). Per run: wall time,
   CPU time (user + system, all threads) and peak resident memory of the process (wait4's
   rusage), and the stage times of its detections.json. The model is trained (untimed) first.
   With --baseline DIR (another build's folder, e.g. of the branch point), every run of ours is
   paired with a run of the baseline build on the same room, the two alternating in order: the
   table then gives both and the ratio of their medians, which is what a comparison on a shared
   machine can trust.
4. Runs build/bin/bench_region_growing on the 1.0M and 3.7M rooms and the office (configs/paper.json's
   radii, 2 threads; --no-pcl skips it): our segmentation + paper24 features against PCL's
   NormalEstimationOMP + RegionGrowing on the same cloud in the same process (PCL / ours, wall
   and CPU time).
5. Prints and writes OUT/dense.md (tables, the machine's load average during the run, and the
   targets: <= 1.0 s per million points end to end on the 1M rooms, >= 15x PCL, linear from
   0.1M to 4M), OUT/dense.json (every measurement) and OUT/dense.svg (time against points, log-log).

--quick: the 0.1M, 1.0M and office rooms, one run each (unless --runs), PCL on the 1.0M room only.
Wall times need a quiet machine (2 cores, nothing else running): on a loaded one read the CPU
times, the per-million ratios between rooms and the in-process PCL ratios.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
import report  # noqa: E402  (svg_plot, points_label)

THREADS = 2
# name, scene, angular step [deg] (no voxel filter): points ~ 1.017M * (0.17 / step)^2 for the demo room.
ROOMS = [
    ("room_0.1M", "data/demo/room.scene.json", 0.54),
    ("room_0.25M", "data/demo/room.scene.json", 0.34),
    ("room_0.5M", "data/demo/room.scene.json", 0.24),
    ("room_1.0M", "data/demo/room.scene.json", 0.17),
    ("room_2M", "data/demo/room.scene.json", 0.12),
    ("room_3.7M", "data/demo/room.scene.json", 0.089),
    ("room_4.1M", "data/demo/room.scene.json", 0.085),
    ("office_1.0M", "benchmarks/speed/office.scene.json", 0.17),
]
QUICK = {"room_0.1M", "room_1.0M", "office_1.0M"}
PCL_ROOMS = ["room_1.0M", "room_3.7M", "office_1.0M"]
TARGET_S_PER_M = 1.0
TARGET_PCL = 15.0


def run(cmd, **kw):
    """Runs cmd; returns (wall s, user + system CPU s, peak RSS MB, return code)."""
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, cwd=ROOT, **kw)
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    p.returncode = os.waitstatus_to_exitcode(status)
    return wall, ru.ru_utime + ru.ru_stime, ru.ru_maxrss / 1024.0, p.returncode


def points_of(pcd):
    with open(pcd, "rb") as f:
        for line in f:
            if line.startswith(b"POINTS"):
                return int(line.split()[1])
            if line.startswith(b"DATA"):
                break
    raise SystemExit(f"dense.py: {pcd}: no POINTS line")


def median(v):
    v = sorted(v)
    n = len(v)
    return v[n // 2] if n % 2 else 0.5 * (v[n // 2 - 1] + v[n // 2])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--build", default="build")
    ap.add_argument("--out", default="runs/dense")
    ap.add_argument("--runs", type=int, help="whole-process runs per room (default 3; 1 with --quick)")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--no-build", action="store_true")
    ap.add_argument("--no-pcl", action="store_true")
    ap.add_argument("--baseline", help="another build folder (its bin/furnihost) or a folder of plugin libraries "
                    "(our furnihost loading them, FURNIHOST_PLUGIN_PATH): alternates with ours on every room")
    args = ap.parse_args()
    os.chdir(ROOT)
    out = args.out
    rooms = [r for r in ROOMS if not args.quick or r[0] in QUICK]
    runs = max(1, args.runs) if args.runs else (1 if args.quick else 3)
    pcl_rooms = ["room_1.0M"] if args.quick else PCL_ROOMS
    fh = os.path.join(args.build, "bin", "furnihost")
    bench = os.path.join(args.build, "bin", "bench_region_growing")
    if not args.no_build:
        subprocess.run(["cmake", "-S", ".", "-B", args.build, "-DCMAKE_BUILD_TYPE=Release", "-DFURNIHOST_BUILD_BENCH=ON"],
                       check=True, stdout=subprocess.DEVNULL)
        subprocess.run(["cmake", "--build", args.build, f"-j{os.cpu_count()}", "--target", "furnihost", "furnihost_plugins",
                        "bench_region_growing"], check=True)
    builds = [("ours", fh, dict(os.environ))]
    if args.baseline:
        if os.path.exists(os.path.join(args.baseline, "bin", "furnihost")):
            builds.append(("baseline", os.path.join(args.baseline, "bin", "furnihost"), dict(os.environ)))
        else:
            # The same plugins of ours from a folder of links, so both load the same libraries the
            # same way (a plugin folder is loaded whole at start-up).
            mine = os.path.abspath(os.path.join(out, "plugins_ours"))
            os.makedirs(mine, exist_ok=True)
            for f in os.listdir(args.baseline):
                link = os.path.join(mine, f)
                if not os.path.lexists(link):
                    os.symlink(os.path.abspath(os.path.join(args.build, "plugins", f)), link)
            builds[0] = ("ours", fh, dict(os.environ, FURNIHOST_PLUGIN_PATH=mine))
            builds.append(("baseline", fh, dict(os.environ, FURNIHOST_PLUGIN_PATH=os.path.abspath(args.baseline))))
    os.makedirs(os.path.join(out, "rooms"), exist_ok=True)
    load = [os.getloadavg()]

    # Rooms.
    pcd = {}
    for name, scene, step in rooms:
        f = os.path.join(out, "rooms", name + ".pcd")
        if not os.path.exists(f):
            params = json.dumps({"angular_resolution_deg": step, "tilt_resolution_deg": step, "voxel_m": 0,
                                 "horizontal_fov_deg": 360})
            subprocess.run([fh, "simulate", "--catalog", "data/demo/catalog.json", "--scene", scene, "--seed", "42",
                            "--threads", str(THREADS), "-q", "--out", f, "--sensor-params", params], check=True)
        pcd[name] = f
    points = {name: points_of(f) for name, f in pcd.items()}

    # The model, trained once before any timed run: each build its own cache (a derived config
    # that only moves configs/paper.json's model_cache into OUT).
    graph = {}
    for label, binary, env in builds:
        graph[label] = os.path.join(out, f"paper_{label}.json")
        with open(graph[label], "w") as f:
            json.dump({"extends": os.path.relpath(os.path.join(ROOT, "configs", "paper.json"), os.path.abspath(out)),
                       "model_cache": f"model_{label}.fhm"}, f)
        # An untimed detection: trains the model when its cache is missing or stale.
        subprocess.run([binary, "--graph", graph[label], pcd[rooms[0][0]], "--threads", str(THREADS), "-q", "--out",
                        os.path.join(out, "detect", label, "warm-up")], check=True, stdout=subprocess.DEVNULL, env=env)

    # Whole processes, interleaved: round r runs every room once (ours and baseline alternating,
    # the order of the two swapped every round).
    meas = {label: {name: [] for name in pcd} for label, _, _ in builds}
    for r in range(runs):
        for name, _, _ in rooms:
            order = builds if r % 2 == 0 else list(reversed(builds))
            for label, binary, env in order:
                dest = os.path.join(out, "detect", label, name)
                cmd = [binary, "--graph", graph[label], pcd[name], "--threads", str(THREADS), "-q", "--out", dest]
                wall, cpu, rss, rc = run(cmd, stdout=subprocess.DEVNULL, env=env)
                if rc != 0:
                    raise SystemExit(f"dense.py: {' '.join(cmd)} failed ({rc})")
                with open(os.path.join(dest, "detections.json")) as f:
                    det = json.load(f)
                meas[label][name].append({"wall_s": wall, "cpu_s": cpu, "peak_rss_mb": rss, "load": os.getloadavg()[0],
                                          "stages_ms": det["timings_ms"], "detections": len(det["detections"])})
                print(f"dense: {label} {name} run {r + 1}/{runs}: {wall:.2f} s wall, {cpu:.2f} s CPU, {rss:.0f} MB",
                      file=sys.stderr)
    load.append(os.getloadavg())

    # Ours against PCL in one process.
    seg = {"rows": []}
    if not args.no_pcl:
        seg_json = os.path.join(out, "segmentation.json")
        cmd = [bench] + [f"--scan={n}={pcd[n]},paper.json" for n in pcl_rooms if n in pcd] + \
              ["--peers=omp", "--ours_iterations=2", "--pcl_iterations=1", f"--summary_json={seg_json}"]
        subprocess.run(cmd, cwd=ROOT, check=True)
        with open(seg_json) as f:
            seg = json.load(f)
    load.append(os.getloadavg())

    # Report.
    def stat(label, name, key):
        return median([m[key] for m in meas[label][name]])

    md = [f"## Dense scans, configs/paper.json, whole process ({THREADS} threads; median of {runs} runs)", "",
          "load average (1, 5, 15 min) at the start, after the processes, at the end: " +
          "; ".join(", ".join(f"{x:.1f}" for x in l) for l in load), ""]
    head = ["room", "points", "wall [s]", "s per M points", "CPU [s]", "CPU s per M", "peak RSS [MB]", "MB per M",
            "segment + features [s]", "fit [s]"]
    if args.baseline:
        head += ["baseline wall [s]", "baseline CPU [s]", "wall ours / baseline", "CPU ours / baseline"]
    md += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    rows = []
    for name, _, _ in sorted(rooms, key=lambda r: points[r[0]]):
        n = points[name]
        m = n / 1e6
        w, c, rss = stat("ours", name, "wall_s"), stat("ours", name, "cpu_s"), stat("ours", name, "peak_rss_mb")
        st = [x["stages_ms"] for x in meas["ours"][name]]
        segfeat = median([s.get("segment", 0) + s.get("features", 0) for s in st]) / 1000
        fit = median([s.get("fit", 0) for s in st]) / 1000
        row = {"room": name, "points": n, "wall_s": w, "cpu_s": c, "peak_rss_mb": rss, "segment_features_s": segfeat,
               "fit_s": fit, "runs": meas["ours"][name]}
        cells = [name, report.points_label(n), f"{w:.2f}", f"{w / m:.2f}", f"{c:.2f}", f"{c / m:.2f}", f"{rss:.0f}",
                 f"{rss / m:.0f}", f"{segfeat:.2f}", f"{fit:.2f}"]
        if args.baseline:
            bw, bc = stat("baseline", name, "wall_s"), stat("baseline", name, "cpu_s")
            row["baseline"] = {"wall_s": bw, "cpu_s": bc, "runs": meas["baseline"][name]}
            cells += [f"{bw:.2f}", f"{bc:.2f}", f"{w / bw:.2f}", f"{c / bc:.2f}"]
        rows.append(row)
        md.append("| " + " | ".join(cells) + " |")

    # Linearity over the demo rooms: the log-log slope of time against points (1 = linear) and
    # the time per million points of the largest room against the smallest's.
    demo = [r for r in rows if r["room"].startswith("room_")]
    lin = {}
    if len(demo) >= 2:
        for key in ("wall_s", "cpu_s", "peak_rss_mb"):
            xs = [math.log(r["points"]) for r in demo]
            ys = [math.log(max(r[key], 1e-9)) for r in demo]
            mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
            slope = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)
            per = [r[key] / (r["points"] / 1e6) for r in demo]
            lin[key] = {"slope": slope, "per_million_smallest": per[0], "per_million_largest": per[-1]}
        md += ["", "Linearity over the demo rooms (log-log slope of the median against points; 1 = linear; per million points "
               "at the smallest and the largest room):",
               ""] + [f"- {k}: slope {v['slope']:.2f}, {v['per_million_smallest']:.2f} -> {v['per_million_largest']:.2f} per M"
                      for k, v in lin.items()]

    md += ["", "## Ours (segmentation + paper24 features) against PCL NormalEstimationOMP + RegionGrowing, one process", ""]
    pcl = []
    if seg["rows"]:
        head = ["room", "points", "ours [s]", "ours CPU [s]", "PCL OMP + RG [s]", "PCL CPU [s]", "x PCL (wall)", "x PCL (CPU)",
                "parts (ours / PCL)"]
        md += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for r in sorted(seg["rows"], key=lambda r: r["points"]):
            o, p = r.get("ours"), r.get("pcl_omp_rg")
            if not o or not p:
                continue
            xw, xc = p["total_ms"] / o["total_ms"], p["cpu_ms"] / max(o["cpu_ms"], 1e-9)
            pcl.append({"room": r["name"], "points": r["points"], "x_wall": xw, "x_cpu": xc, "ours": o, "pcl_omp_rg": p})
            md.append("| " + " | ".join([r["name"], report.points_label(r["points"]), f"{o['total_ms'] / 1000:.2f}",
                                         f"{o['cpu_ms'] / 1000:.2f}", f"{p['total_ms'] / 1000:.2f}",
                                         f"{p['cpu_ms'] / 1000:.2f}", f"{xw:.1f}", f"{xc:.1f}",
                                         f"{o['parts']} / {p['parts']}"]) + " |")
    else:
        md.append("(not run)")

    md += ["", "## Targets", ""]
    for r in rows:
        if r["room"] in ("room_1.0M", "room_3.7M", "office_1.0M"):
            spm = r["wall_s"] / (r["points"] / 1e6)
            md.append(f"- {r['room']}: {spm:.2f} s per million points end to end "
                      f"({'met' if spm <= TARGET_S_PER_M else 'not met'}: <= {TARGET_S_PER_M}); "
                      f"CPU {r['cpu_s'] / (r['points'] / 1e6):.2f} s per million")
    for p in pcl:
        md.append(f"- {p['room']}: {p['x_wall']:.1f}x PCL OMP + RG in wall time, {p['x_cpu']:.1f}x in CPU time "
                  f"({'met' if p['x_wall'] >= TARGET_PCL else 'not met'}: >= {TARGET_PCL}x)")
    if "wall_s" in lin:
        md.append(f"- linear from {report.points_label(demo[0]['points'])} to {report.points_label(demo[-1]['points'])}: "
                  f"slope {lin['wall_s']['slope']:.2f} (wall), {lin['cpu_s']['slope']:.2f} (CPU)")
    text = "\n".join(md) + "\n"
    print(text)
    with open(os.path.join(out, "dense.md"), "w") as f:
        f.write(text)
    with open(os.path.join(out, "dense.json"), "w") as f:
        json.dump({"threads": THREADS, "runs": runs, "load": load, "rooms": rows, "linearity": lin, "pcl": pcl}, f, indent=1)
    series = [("whole process (wall)", "#1f77b4", [(r["points"], r["wall_s"]) for r in demo]),
              ("whole process (CPU / 2)", "#9467bd", [(r["points"], r["cpu_s"] / THREADS) for r in demo]),
              ("segment + features", "#2ca02c", [(r["points"], r["segment_features_s"]) for r in demo]),
              ("PCL OMP + RG", "#ff7f0e", [(p["points"], p["pcl_omp_rg"]["total_ms"] / 1000) for p in pcl
                                           if p["room"].startswith("room_")])]
    report.svg_plot(series, os.path.join(out, "dense.svg"), "configs/paper.json on the demo room, 0.1M to 4M points")
    print(f"wrote {out}/dense.md, dense.json and dense.svg")


if __name__ == "__main__":
    main()
