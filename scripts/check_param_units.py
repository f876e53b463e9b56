#!/usr/bin/env python3
"""Checks that every numeric parameter (Number, Int, NumberList, NumberMap) of every plugin in a
folder, and of the host's sections of a graph config, declares a unit: a physical one as it is (m, m2, deg, px, s, 1/m ...), "count" for counts,
"1" for dimensionless ratios, fractions, scores, probabilities and IoUs.

  scripts/check_param_units.py --furnihost build/bin/furnihost --plugin-dir build/plugins

Reads `furnihost plugins --json` (the plugins found in --plugin-dir only). Prints one line per
parameter without a unit ("<plugin type>: <parameter> (<type>)") and exits 1 when there is any,
0 when every numeric parameter has one; exit 2 on bad usage, when furnihost fails or when the
folder holds no plugin.
"""
import argparse
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from plugin_docs import read_plugins  # noqa: E402  (the same listing the plugin pages are made from)

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
    plugins, sections = read_plugins(args.furnihost, args.plugin_dir)  # exits 2 on failure, as plugin_docs does
    # The host's own sections of a graph config (ground, frame, ensemble) are held to the same rule.
    listed = sorted(plugins, key=lambda p: p.get("type", ""))
    listed += [{"type": f"host section {name}", "params": params} for name, params in sorted(sections.items())]
    checked, missing = 0, []
    for p in listed:
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
