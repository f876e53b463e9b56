#!/usr/bin/env bash
# Regenerates benchmarks/synthetic/*.pcd and .gt.json from their scene files with `furnihost simulate`.
set -euo pipefail
cd "$(dirname "$0")/.."
FURNIHOST=${FURNIHOST:-build/bin/furnihost}
for scene in benchmarks/synthetic/*.scene.json; do
  "$FURNIHOST" simulate --catalog data/demo/catalog.json --scene "$scene" --out "${scene%.scene.json}.pcd" --seed 42
done
