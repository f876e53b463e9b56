#!/usr/bin/env python3
"""Tables and plot of a benchmarks/speed/run.sh run.

    python3 benchmarks/speed/report.py runs/speed [--doc docs/performance.md]

Reads DIR/detect/<scan>/run*/detections.json (timings_ms per stage; the run with the smallest
total is kept), DIR/scannet_route.json (configs/scannet.json timed as whole processes) and
DIR/segmentation.json (bench_region_growing --summary_json). Prints two
markdown tables, writes them to DIR/speed.md and a plot of time against point count to
DIR/speed.svg (written by hand: no plotting library needed). --doc PATH also writes the tables
as the project's performance page (PATH, with the date, commit, machine and load of the run) and
the plot beside it (img/performance.svg under PATH's folder).
"""
import glob
import json
import math
import os
import shutil
import subprocess
import sys
import time


def load_detect(out):
    rows = {}
    for d in sorted(glob.glob(os.path.join(out, "detect", "*"))):
        runs = []
        for f in glob.glob(os.path.join(d, "run*", "detections.json")):
            with open(f) as fh:
                runs.append(json.load(fh))
        if runs:
            rows[os.path.basename(d)] = min(runs, key=lambda j: j["timings_ms"]["total"])
    return rows


def fmt_ms(ms):
    return f"{ms / 1000:.2f}" if ms >= 1000 else f"{ms / 1000:.3f}"


def points_label(n, digits=2):
    return f"{n / 1e6:.{digits}f}M" if n >= 1e6 else f"{n / 1e3:.0f}k"


def nice_below(v):
    """Largest 1, 2 or 5 x 10^k not above v."""
    d = 10 ** math.floor(math.log10(v))
    return max(m * d for m in (1, 2, 5) if m * d <= v * 1.0001)


def nice_above(v):
    d = 10 ** math.floor(math.log10(v))
    return min(m * d for m in (1, 2, 5, 10) if m * d >= v * 0.9999)


def detect_table(det):
    # detections.json's keys come sorted; show paper.json's stages in pipeline order.
    order = ["input", "ground", "segment", "features", "vote", "fit"]
    stages = []
    for j in det.values():
        for t in j["timings_ms"]:
            if t != "total" and t not in stages:
                stages.append(t)
    stages.sort(key=lambda t: (order.index(t) if t in order else len(order), t))
    head = ["scan", "points"] + [f"{s} [s]" for s in stages] + ["total [s]", "µs/point"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name, j in sorted(det.items(), key=lambda kv: kv[1]["points"]):
        t = j["timings_ms"]
        cells = [name, points_label(j["points"])] + [fmt_ms(t.get(s, 0.0)) for s in stages]
        cells += [fmt_ms(t["total"]), f"{1000 * t['total'] / max(1, j['points']):.1f}"]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def seg_table(seg):
    head = ["scan", "points", "ours: normals + growing + features [s]", "PCL MLS + RG [s]", "× ours",
            "PCL OMP + RG [s]", "× ours", "parts (ours / MLS / OMP)"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in sorted(seg["rows"], key=lambda r: r["points"]):
        o, m, p = r.get("ours"), r.get("pcl_mls_rg"), r.get("pcl_omp_rg")
        def ratio(x):
            return f"{x['total_ms'] / o['total_ms']:.1f}" if x and o and o["total_ms"] > 0 else "-"
        ours = (f"{fmt_ms(o['total_ms'])} ({fmt_ms(o['normals_ms'])} + {fmt_ms(o['growing_ms'])} + "
                f"{fmt_ms(o['features_ms'])})") if o else "-"
        cells = [r["name"], points_label(r["points"]), ours,
                 fmt_ms(m["total_ms"]) if m else "-", ratio(m),
                 fmt_ms(p["total_ms"]) if p else "-", ratio(p),
                 " / ".join(str(x["parts"]) if x else "-" for x in (o, m, p))]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def route_table(route):
    """configs/scannet.json as whole processes: per room the median, fastest and slowest."""
    by_room = {}
    for r in route["runs"]:
        by_room.setdefault(r["room"], []).append(r)
    head = ["room", "points", "process [s]: median (min-max)", "runs", "stages [s]: ground + proposals + recognition",
            "< 0.3 s"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for room, runs in sorted(by_room.items()):
        walls = sorted(r["wall_s"] for r in runs)
        med = walls[len(walls) // 2] if len(walls) % 2 else 0.5 * (walls[len(walls) // 2 - 1] + walls[len(walls) // 2])
        t = min((r["detections"]["timings_ms"] for r in runs), key=lambda t: t["total"])
        stages = " + ".join(f"{t.get(s, 0.0) / 1000:.3f}" for s in ("ground", "propose", "recognise"))
        cells = [room, points_label(runs[0]["detections"]["points"]), f"{med:.3f} ({walls[0]:.3f}-{walls[-1]:.3f})",
                 str(len(walls)), stages, "yes" if med < 0.3 else "no"]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def views_table(views):
    """Single views (configs/rgbd_view.json) and one-spot laser rooms (configs/laser_room.json) as whole
    processes: per scan the median, fastest and slowest, against the target of its kind."""
    by_scan = {}
    for r in views["runs"]:
        by_scan.setdefault((r["kind"], r["graph"], r["scan"]), []).append(r)
    target = {"view": 0.3, "room": 0.6}
    head = ["graph", "scan", "points", "process [s]: median (min-max)", "runs",
            "stages [s]: ground + proposals + recognition + synthesis", "target", "met"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for (kind, graph, scan), runs in sorted(by_scan.items()):
        walls = sorted(r["wall_s"] for r in runs)
        med = walls[len(walls) // 2] if len(walls) % 2 else 0.5 * (walls[len(walls) // 2 - 1] + walls[len(walls) // 2])
        t = min((r["detections"]["timings_ms"] for r in runs), key=lambda t: t["total"])
        stages = " + ".join(f"{t.get(s, 0.0) / 1000:.3f}" for s in ("ground", "propose", "recognise", "fit"))
        cells = [graph, scan, points_label(runs[0]["detections"]["points"]), f"{med:.3f} ({walls[0]:.3f}-{walls[-1]:.3f})",
                 str(len(walls)), stages, f"{target[kind]:.1f} s", "yes" if med <= target[kind] else "no"]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def svg_plot(series, path, title, xlabel="points", ylabel="time [s] (2 threads)"):
    """series: [(label, colour, [(x, seconds), ...])]; log-log axes."""
    W, H, L, R, T, B = 640, 420, 70, 190, 40, 50
    xs = [x for _, _, pts in series for x, _ in pts]
    ys = [y for _, _, pts in series for _, y in pts if y > 0]
    if not xs or not ys:
        return
    x0, x1 = nice_below(min(xs)), nice_above(max(xs))
    y0, y1 = nice_below(min(ys)), nice_above(max(ys))
    px = lambda x: L + (math.log10(x) - math.log10(x0)) / (math.log10(x1) - math.log10(x0)) * (W - L - R)
    py = lambda y: H - B - (math.log10(y) - math.log10(y0)) / (math.log10(y1) - math.log10(y0)) * (H - T - B)
    o = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" font-size="12">',
         f'<rect width="{W}" height="{H}" fill="white"/>',
         f'<text x="{L}" y="22" font-size="14">{title}</text>']
    decade = 10 ** math.floor(math.log10(x0))
    while decade <= x1 * 1.0001:
        for m in range(1, 10):
            v = decade * m
            if v < x0 * 0.9999 or v > x1 * 1.0001:
                continue
            X = px(v)
            o.append(f'<line x1="{X:.1f}" y1="{T}" x2="{X:.1f}" y2="{H - B}" stroke="#{"ccc" if m == 1 else "eee"}"/>')
            if m in (1, 2, 5):
                o.append(f'<text x="{X:.1f}" y="{H - B + 16}" text-anchor="middle">{points_label(v, 0)}</text>')
        decade *= 10
    decade = 10 ** math.floor(math.log10(y0))
    while decade <= y1 * 1.0001:
        for m in range(1, 10):
            v = decade * m
            if v < y0 * 0.9999 or v > y1 * 1.0001:
                continue
            Y = py(v)
            o.append(f'<line x1="{L}" y1="{Y:.1f}" x2="{W - R}" y2="{Y:.1f}" stroke="#{"ccc" if m == 1 else "eee"}"/>')
            if m in (1, 2, 5):
                o.append(f'<text x="{L - 6}" y="{Y + 4:.1f}" text-anchor="end">{v:g}</text>')
        decade *= 10
    o.append(f'<rect x="{L}" y="{T}" width="{W - L - R}" height="{H - T - B}" fill="none" stroke="black"/>')
    o.append(f'<text x="{(L + W - R) / 2}" y="{H - 12}" text-anchor="middle">{xlabel}</text>')
    o.append(f'<text transform="translate(16 {(T + H - B) / 2}) rotate(-90)" text-anchor="middle">{ylabel}</text>')
    for i, (label, colour, pts) in enumerate(series):
        pts = sorted(p for p in pts if p[1] > 0)
        if not pts:
            continue
        path_d = " ".join(f"{'M' if k == 0 else 'L'}{px(x):.1f},{py(y):.1f}" for k, (x, y) in enumerate(pts))
        o.append(f'<path d="{path_d}" fill="none" stroke="{colour}" stroke-width="2"/>')
        for x, y in pts:
            o.append(f'<circle cx="{px(x):.1f}" cy="{py(y):.1f}" r="3.5" fill="{colour}"/>')
        ly = T + 14 + 20 * i
        o.append(f'<line x1="{W - R + 12}" y1="{ly - 4}" x2="{W - R + 32}" y2="{ly - 4}" stroke="{colour}" stroke-width="2"/>')
        o.append(f'<text x="{W - R + 38}" y="{ly}">{label}</text>')
    o.append("</svg>")
    with open(path, "w") as fh:
        fh.write("\n".join(o) + "\n")


def run_facts(out):
    """Date, commit, CPU, cores and load: what the figures of a run depend on."""
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], capture_output=True,
                               text=True, check=True).stdout.strip()
        commit += " + uncommitted changes" if dirty else ""
    except (OSError, subprocess.CalledProcessError):
        commit = "unknown"
    cpu = "unknown"
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    when = time.strftime("%Y-%m-%d", time.gmtime(os.path.getmtime(out)))
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return when, commit, cpu, os.cpu_count(), load


def write_doc(path, out, tables):
    when, commit, cpu, cores, load = run_facts(out)
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(os.path.join(folder, "img"), exist_ok=True)
    shutil.copyfile(os.path.join(out, "speed.svg"), os.path.join(folder, "img", "performance.svg"))
    head = ["# Performance", "",
            "<!-- Written by benchmarks/speed/run.sh --doc (benchmarks/speed/report.py): do not edit. -->", "",
            f"Measured on {when} at commit {commit}, on {cpu} ({cores} cores; load average {load:.1f} when the "
            "tables were written). Times are of this machine; the ratios against PCL are of runs in one process, "
            "on the same clouds, and move less with the load. How to run it: "
            "[benchmarks/README.md](../benchmarks/README.md#speed).", "",
            "![time against point count](img/performance.svg)", "", ""]
    tmp = path + ".tmp"
    with open(tmp, "w") as fh:
        fh.write("\n".join(head) + tables)
    os.replace(tmp, path)
    print(f"wrote {path} and {os.path.join(folder, 'img', 'performance.svg')}")


def main():
    args = sys.argv[1:]
    doc = None
    if "--doc" in args:
        i = args.index("--doc")
        if i + 1 >= len(args):
            print("report.py: --doc needs a path", file=sys.stderr)
            sys.exit(2)
        doc = args[i + 1]
        del args[i:i + 2]
    out = args[0] if args else "runs/speed"
    det = load_detect(out)
    seg_path = os.path.join(out, "segmentation.json")
    seg = json.load(open(seg_path)) if os.path.exists(seg_path) else {"rows": []}
    md = ["## Whole detection, configs/paper.json (fastest of the runs; 2 threads)", ""]
    md += detect_table(det) if det else ["(no detection runs)"]
    route_path = os.path.join(out, "scannet_route.json")
    route = json.load(open(route_path)) if os.path.exists(route_path) else {"runs": []}
    if route["runs"]:
        md += ["", "## configs/scannet.json on ScanNet dev rooms, whole process (model cached; 2 threads)", ""]
        md += route_table(route)
    views_path = os.path.join(out, "views_route.json")
    views = json.load(open(views_path)) if os.path.exists(views_path) else {"runs": []}
    if views["runs"]:
        md += ["", "## Single views and one-spot laser rooms, whole process (model cached; 2 threads)", ""]
        md += views_table(views)
    md += ["", "## Segmentation (+ features) against PCL on the same clouds, one process (2 threads)", ""]
    md += seg_table(seg) if seg["rows"] else ["(no segmentation rows)"]
    md += ["", "Each contender's fastest timed run. × ours = PCL time / our time (higher: ours faster). PCL RegionGrowing is single-threaded;",
           "its normals (MLS order 2 / NormalEstimationOMP) use 2 threads. Radii: configs/paper.json."]
    text = "\n".join(md) + "\n"
    print(text)
    with open(os.path.join(out, "speed.md"), "w") as fh:
        fh.write(text)
    laser = lambda name: not name.startswith("scannet")
    rows = seg["rows"]
    series = [
        ("detection (total)", "#1f77b4",
         [(j["points"], j["timings_ms"]["total"] / 1000) for n, j in det.items() if laser(n)]),
        ("ours: seg + features", "#2ca02c",
         [(r["points"], r["ours"]["total_ms"] / 1000) for r in rows if "ours" in r and laser(r["name"])]),
        ("PCL MLS + RG", "#d62728",
         [(r["points"], r["pcl_mls_rg"]["total_ms"] / 1000) for r in rows if "pcl_mls_rg" in r and laser(r["name"])]),
        ("PCL OMP + RG", "#ff7f0e",
         [(r["points"], r["pcl_omp_rg"]["total_ms"] / 1000) for r in rows if "pcl_omp_rg" in r and laser(r["name"])]),
    ]
    svg_plot(series, os.path.join(out, "speed.svg"), "furnihost speed on simulated laser rooms (configs/paper.json)")
    print(f"wrote {out}/speed.md and {out}/speed.svg")
    if doc:
        write_doc(doc, out, text)


if __name__ == "__main__":
    main()
