#!/usr/bin/env bash
# Regenerates the synthetic benchmark scans (*.pcd) and ground truth (*.gt.json) from their
# scene files with `furnihost simulate`:
#   benchmarks/synthetic/          objects from data/demo/catalog.json (NOT in the training catalog)
#   benchmarks/synthetic_catalog/  objects from data/catalog/catalog.json (the training catalog:
#                                  measures model fitting and verification on exact models)
# FURNIHOST=path/to/furnihost overrides the binary (add --plugin-path via FURNIHOST_ARGS).
set -euo pipefail
cd "$(dirname "$0")/.."
FURNIHOST=${FURNIHOST:-build/bin/furnihost}
read -r -a EXTRA <<< "${FURNIHOST_ARGS:-}"
simulate() {  # catalog, folder
  for scene in "$2"/*.scene.json; do
    "$FURNIHOST" simulate "${EXTRA[@]}" --catalog "$1" --scene "$scene" --out "${scene%.scene.json}.pcd" --seed 42
  done
}
simulate data/demo/catalog.json benchmarks/synthetic
simulate data/catalog/catalog.json benchmarks/synthetic_catalog
