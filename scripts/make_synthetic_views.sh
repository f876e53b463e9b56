#!/usr/bin/env bash
# Makes the synthetic single-view benchmark (benchmarks/synthetic_views.json): each scene of
# benchmarks/synthetic_views/ seen by two depth cameras (320 x 240, Kinect-like optics, refined
# depth noise 2 mm + 1 mm/m^2, 5 % dropout), one scan per camera in its upright frame (camera at
# the origin, floor below it, as SUN RGB-D's views), objects with fewer than 200 returns left out
# of the ground truth. The models come from the shared catalog (../shared/data/cad_catalog), whose
# terms do not allow the scans to be shipped: they are made here, in seconds.
# FURNIHOST=path/to/furnihost overrides the binary.
set -euo pipefail
cd "$(dirname "$0")/.."
FURNIHOST=${FURNIHOST:-build/bin/furnihost}
CATALOG=${FURNIHOST_SHARED_CATALOG:-../shared/data/cad_catalog/catalog.json}
for scene in benchmarks/synthetic_views/*.scene.json; do
  name=$(basename "$scene" .scene.json)
  "$FURNIHOST" simulate -q --catalog "$CATALOG" --scene "$scene" --out "benchmarks/synthetic_views/$name.ply" \
    --per-sensor --sensor-frame --min-visible 200 --seed 1
done
