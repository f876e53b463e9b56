#!/usr/bin/env python3
"""`furnihost eval` of the ScanNet dev set as one rank, as two MPI ranks and as one process of two
threads: wall and CPU time, alternated run by run.

    benchmarks/mpi/scaling.py [--runs N] [--seeds S] [--graph G] [--dataset D] [--build DIR] [--out DIR]

Per round (--runs, default 3) it runs, in an order that rotates every round:
  1 rank    furnihost eval --threads 1 --jobs 1               (one thread, one scene at a time)
  2 ranks   mpirun -n 2 furnihost eval --threads 1            (one thread per rank)
  2 threads furnihost eval --threads 2                        (one process, two scenes at a time)
each with --reproducible (so all three write the same summary.json: checked), the model cached
first. It prints the medians, the ratios 1 rank / 2 ranks (target >= 1.7) and 2 threads / 2 ranks
(target >= 1.0), the CPU time of each (user + system of the process and its children) and the
machine's load average: on a loaded machine the wall-time ratios mean little, the CPU times say
what the runs cost. As root it sets OMPI_ALLOW_RUN_AS_ROOT(_CONFIRM); it passes --oversubscribe.
"""
import argparse
import filecmp
import os
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def timed(cmd, env):
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    err = p.stderr.read().decode(errors="replace")
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"scaling.py: {' '.join(cmd)} failed:\n{err[-2000:]}")
    return wall, ru.ru_utime + ru.ru_stime


def median(v):
    v = sorted(v)
    return v[len(v) // 2] if len(v) % 2 else 0.5 * (v[len(v) // 2 - 1] + v[len(v) // 2])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--graph", default="configs/scannet.json")
    ap.add_argument("--dataset", default="benchmarks/scannet_dev.json")
    ap.add_argument("--build", default="build")
    ap.add_argument("--out", default="runs/mpi_scaling")
    args = ap.parse_args()
    fh = os.path.join(args.build, "bin", "furnihost")
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    base = [fh, "eval", "--graph", args.graph, "--dataset", args.dataset, "--seeds", str(args.seeds), "-q", "--reproducible"]
    variants = {
        "1 rank": lambda out: base + ["--out", out, "--threads", "1", "--jobs", "1"],
        "2 ranks": lambda out: ["mpirun", "--oversubscribe", "-n", "2"] + base + ["--out", out, "--threads", "1"],
        "2 threads": lambda out: base + ["--out", out, "--threads", "2"],
    }
    names = list(variants)
    load = [os.getloadavg()]
    timed(variants["1 rank"](os.path.join(args.out, "warm-up")), env)  # trains the model if its cache is stale
    wall = {n: [] for n in names}
    cpu = {n: [] for n in names}
    for r in range(args.runs):
        order = names[r % 3:] + names[:r % 3]
        for n in order:
            out = os.path.join(args.out, n.replace(" ", "_"))
            w, c = timed(variants[n](out), env)
            wall[n].append(w)
            cpu[n].append(c)
            print(f"scaling: round {r + 1}: {n}: {w:.2f} s wall, {c:.2f} s CPU", file=sys.stderr)
    load.append(os.getloadavg())
    same = all(filecmp.cmp(os.path.join(args.out, "1_rank", "summary.json"), os.path.join(args.out, d, "summary.json"),
                           shallow=False) for d in ("2_ranks", "2_threads"))
    m = {n: median(wall[n]) for n in names}
    print(f"## furnihost eval {args.graph} on {args.dataset}, {args.seeds} seed(s), median of {args.runs} alternated runs\n")
    print("load average (1, 5, 15 min) before and after: " + "; ".join(", ".join(f"{x:.1f}" for x in l) for l in load) + "\n")
    print("| run | wall [s] | CPU [s] | runs (wall) |")
    print("|---|---|---|---|")
    for n in names:
        print(f"| {n} | {m[n]:.2f} | {median(cpu[n]):.2f} | {', '.join(f'{x:.2f}' for x in wall[n])} |")
    print(f"\n- 1 rank / 2 ranks: {m['1 rank'] / m['2 ranks']:.2f}x (target >= 1.7)")
    print(f"- 2 threads / 2 ranks: {m['2 threads'] / m['2 ranks']:.2f}x (target >= 1.0: two ranks no slower)")
    print(f"- summary.json of the three byte for byte the same: {'yes' if same else 'NO'}")


if __name__ == "__main__":
    main()
