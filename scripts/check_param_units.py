#!/usr/bin/env python3
"""Checks that every numeric parameter (Number, Int, NumberList, NumberMap) of every plugin in a
folder declares a unit: a physical one as it is (m, m2, deg, px, s, 1/m ...), "count" for counts,
"1" for dimensionless ratios, fractions, scores, probabilities and IoUs.

  scripts/check_param_units.py --furnihost build/bin/furnihost --plugin-dir build/plugins

Reads `furnihost plugins --json` (the plugins found in --plugin-dir only). Prints one line per
parameter without a unit ("<plugin type>: <parameter> (<type>)") and exits 1 when there is any,
0 when every numeric parameter has one; exit 2 on bad usage, when furnihost fails or when the
folder holds no plugin.
"""
import argparse
import json
import os
import pathlib
import subprocess
import sys

# The types of `furnihost plugins --json` (ParamType Number, Int, NumberList, NumberMap).
NUMERIC = {"number", "int", "number[]", "{name: number}"}


def fail(msg):
    print(f"check_param_units: {msg}", file=sys.stderr)
    sys.exit(2)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--furnihost", required=True, help="the furnihost binary")
    ap.add_argument("--plugin-dir", required=True, help="the folder of the plugins to check")
    args = ap.parse_args()
    env = dict(os.environ)
    env.pop("FURNIHOST_PLUGIN_PATH", None)  # the given folder alone
    cmd = [args.furnihost, "plugins", "--json", "--plugin-path", args.plugin_dir]
    try:
        run = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)
    except (OSError, subprocess.TimeoutExpired) as e:
        fail(f"{' '.join(cmd)}: {e}")
    if run.returncode != 0:
        fail(f"{' '.join(cmd)} exited {run.returncode}: {run.stderr.strip()[:500]}")
    try:
        listing = json.loads(run.stdout)
    except json.JSONDecodeError as e:
        fail(f"{' '.join(cmd)}: output is not JSON ({e})")
    root = pathlib.Path(args.plugin_dir).resolve()
    checked, missing = 0, []
    for p in sorted(listing.get("plugins", []), key=lambda p: p.get("type", "")):
        path = pathlib.Path(p.get("path", "")).resolve()
        if root != path and root not in path.parents:
            continue
        for s in p.get("params", []):
            if s.get("type") not in NUMERIC:
                continue
            checked += 1
            if not str(s.get("unit", "")).strip():
                missing.append(f"{p['type']}: {s['name']} ({s['type']})")
    if not checked:
        fail(f"no numeric parameter of a plugin in {args.plugin_dir}")
    for line in missing:
        print(line)
    if missing:
        print(f"check_param_units: {len(missing)} of {checked} numeric parameters have no unit", file=sys.stderr)
        return 1
    print(f"check_param_units: all {checked} numeric parameters have a unit")
    return 0


if __name__ == "__main__":
    sys.exit(main())
