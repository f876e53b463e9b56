#!/usr/bin/env python3
"""What a detection costs from Python against the command line, as whole processes.

    PYTHONPATH=build/python /usr/bin/python3 benchmarks/speed/python_vs_cli.py [--runs 9] [--graph G]
        [SCAN ...]

Times, alternated run by run (the machine's load moves both alike), on each scan (default: three
ScanNet dev rooms of 50k points, configs/scannet.json, the model cached first):
  cli      `furnihost --graph G -q --out TMP SCAN` (reads, detects, writes detections.json, the
           plots and fitted.ply);
  python   `python3 -c "import furnihost; read_scan; Graph(G).detect(points, colors)"`: the
           interpreter's start, importing furnihost (and numpy), reading the scan into arrays,
           one detection;
  python+path  the same detecting in the file's path instead of arrays;
  session  in a Python process that already holds the cloud in numpy arrays (numpy imported, as
           in a notebook): `import furnihost`, Graph(G) and one detection, timed inside it.
Prints the medians of wall time and CPU time (user + system, every thread: the steadier figure
on a loaded machine) in seconds and the ratios session / cli.
"""
import argparse
import json
import pathlib
import resource
import statistics
import subprocess
import sys
import tempfile
import time

import numpy

import furnihost

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCANS = [ROOT.parent / "shared/data/scannet_votenet50k" / f"{s}.ply" for s in ("scene0000_00", "scene0001_01",
                                                                              "scene0003_00")]
PY_ARRAYS = ("import sys, furnihost; g = furnihost.Graph(sys.argv[1]); p, c = furnihost.read_scan(sys.argv[2]); "
             "d = g.detect(p, c); assert d")
PY_PATH = "import sys, furnihost; assert furnihost.Graph(sys.argv[1]).detect(sys.argv[2])"
# A Python session that holds the cloud in numpy already (numpy imported, the arrays loaded):
# what `import furnihost` and one detection add to it, as the process's wall and CPU time.
PY_SESSION = """
import json, resource, sys, time
import numpy
points, colors = numpy.load(sys.argv[2]), numpy.load(sys.argv[3])
def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime
t, c = time.perf_counter(), cpu()
import furnihost
assert furnihost.Graph(sys.argv[1]).detect(points, colors)
print(json.dumps([time.perf_counter() - t, cpu() - c]))
"""


def timed(cmd):
    """(wall, CPU) seconds of a process: its user + system time, all its threads."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def session(graph, points, colors):
    """(wall, CPU) seconds of `import furnihost` plus one detection in a session holding the cloud."""
    r = subprocess.run([sys.executable, "-c", PY_SESSION, graph, points, colors], check=True, capture_output=True,
                       text=True)
    return tuple(json.loads(r.stdout.strip().splitlines()[-1]))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scans", nargs="*", default=SCANS)
    ap.add_argument("--graph", default=str(ROOT / "configs" / "scannet.json"))
    ap.add_argument("--binary", default=str(ROOT / "build" / "bin" / "furnihost"))
    ap.add_argument("--runs", type=int, default=9)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as out:
        subprocess.run([args.binary, "--graph", args.graph, "-q", "--out", out, str(args.scans[0])], check=True,
                       stdout=subprocess.DEVNULL)  # the model cached, the files in the page cache
        print("| scan | cli process: wall, CPU [s] | python process, arrays | python process, path | "
              "import furnihost + detect in a numpy session | session / cli: wall, CPU |")
        print("|---|---:|---:|---:|---:|---:|")
        for scan in args.scans:
            points, colors = furnihost.read_scan(scan)  # the session's cloud
            held = [str(pathlib.Path(out) / "points.npy"), str(pathlib.Path(out) / "colors.npy")]
            numpy.save(held[0], points)
            numpy.save(held[1], colors)
            runs = {"cli": [], "arrays": [], "path": [], "session": []}
            for _ in range(args.runs):
                runs["cli"].append(timed([args.binary, "--graph", args.graph, "-q", "--out", out, str(scan)]))
                runs["arrays"].append(timed([sys.executable, "-c", PY_ARRAYS, args.graph, str(scan)]))
                runs["path"].append(timed([sys.executable, "-c", PY_PATH, args.graph, str(scan)]))
                runs["session"].append(session(args.graph, *held))
            wall = {k: statistics.median(w for w, _ in v) for k, v in runs.items()}
            cpu = {k: statistics.median(c for _, c in v) for k, v in runs.items()}
            cell = {k: f"{wall[k]:.3f}, {cpu[k]:.3f}" for k in runs}
            print(f"| {pathlib.Path(scan).stem} | {cell['cli']} | {cell['arrays']} | {cell['path']} | "
                  f"{cell['session']} | {wall['session'] / wall['cli']:.2f}, {cpu['session'] / cpu['cli']:.2f} |",
                  flush=True)


if __name__ == "__main__":
    main()
