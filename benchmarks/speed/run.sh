#!/usr/bin/env bash
# Speed benchmark in one command: builds furnihost and bench_region_growing
# (-DFURNIHOST_BUILD_BENCH=ON), simulates dense laser rooms of ~0.1M, 0.5M and 1.5M points, times
# `furnihost --graph configs/paper.json` per stage on them and on one ScanNet dev scan, times
# `furnihost --graph configs/scannet.json` as whole processes on three ScanNet rooms, times our
# segmentation + features against PCL's MLS + RegionGrowing and NormalEstimationOMP +
# RegionGrowing on the same clouds in one process, then prints markdown tables and writes a plot.
#
#   benchmarks/speed/run.sh [--quick] [--build DIR] [--out DIR] [--no-build] [--doc docs/performance.md]
#
# --doc PATH: also writes the tables as the project's performance page (docs/performance.md,
# with the date, commit, machine and load of the run, and docs/img/performance.svg).
#
# --quick: the 0.1M and 0.5M rooms and ScanNet only (~1 min once built). Full run: ~5 min on
# 2 cores once built. Each measurement is one run (the 1.5M room costs about a minute per
# pipeline); REPEATS=N makes it N detection runs per scan (the fastest is reported) and N
# benchmark iterations (the fastest is reported; below 0.5M points at least 10 of ours and 3 of
# each PCL peer, after one untimed run each). The model is trained once and cached, not timed.
# MAX_NORMAL_POINTS=K sets segmenters.region_growing's max_normal_points (detection and
# benchmark); the detection then retrains the model and overwrites the cached one (the next
# run without it retrains again).
# Writes DIR (default runs/speed/): rooms/*.pcd, detect/<scan>/run<i>/detections.json,
# scannet_route.json (configs/scannet.json timed as whole processes on ScanNet dev rooms,
# PROCESS_RUNS=N runs each, default 5), views_route.json (configs/rgbd_view.json on SUN RGB-D
# views and configs/laser_room.json on laser rooms, the same way), segmentation.json, speed.md (the tables) and speed.svg
# (time against point count).
# $FURNIHOST_SHARED_DATA_DIR (default ../shared/data) holds scannet_votenet50k/; it is read in
# place, never copied.
set -euo pipefail
cd "$(dirname "$0")/../.."

BUILD=build
OUT=runs/speed
QUICK=0
DO_BUILD=1
DOC_ARGS=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --quick) QUICK=1 ;;
    --build) BUILD="$2"; shift ;;
    --out) OUT="$2"; shift ;;
    --no-build) DO_BUILD=0 ;;
    --doc) DOC_ARGS=(--doc "$2"); shift ;;
    -h|--help) sed -n '2,/^set /{/^#/p}' "$0"; exit 0 ;;
    *) echo "run.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
  shift
done
SHARED="${FURNIHOST_SHARED_DATA_DIR:-../shared/data}"
SCANNET="$SHARED/scannet_votenet50k/scene0001_00.ply"
THREADS=2  # the target machine; bench_region_growing uses 2 threads too

if [[ $DO_BUILD == 1 ]]; then
  cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=Release -DFURNIHOST_BUILD_BENCH=ON >/dev/null
  cmake --build "$BUILD" -j"$(nproc)" --target furnihost furnihost_plugins bench_region_growing
fi
FH="$BUILD/bin/furnihost"
mkdir -p "$OUT/rooms" "$OUT/detect"

# data/demo/room.scene.json with its own sensor (a 360 deg pan-tilt scan from the room centre,
# see data/demo/room.gt.json), denser: finer angular steps and a finer (or no) voxel filter.
#   name        angular/tilt step [deg]  voxel [m]
ROOMS=("room_0.1M 0.25 0.04" "room_0.5M 0.25 0" "room_1.5M 0.14 0")
[[ $QUICK == 1 ]] && ROOMS=("${ROOMS[@]:0:2}")
SCANS=()
for r in "${ROOMS[@]}"; do
  read -r name step voxel <<<"$r"
  f="$OUT/rooms/$name.pcd"
  if [[ ! -s $f ]]; then
    "$FH" simulate --catalog data/demo/catalog.json --scene data/demo/room.scene.json --seed 42 \
      --threads "$THREADS" -q --out "$f" \
      --sensor-params "{\"angular_resolution_deg\": $step, \"tilt_resolution_deg\": $step, \"voxel_m\": $voxel}"
  fi
  SCANS+=("$name=$f")
done
if [[ -f $SCANNET ]]; then
  SCANS+=("scannet_0001_00=$SCANNET")
else
  echo "run.sh: $SCANNET not found: the ScanNet row is skipped" >&2
fi

# Whole detection, per stage (timings_ms of detections.json); report.py keeps a scan's fastest run.
# The first detection trains the model if furnihost-out/models/ has no valid one; training is
# outside timings_ms.
REPEATS=${REPEATS:-1}
SET_ARGS=()
[[ -n ${MAX_NORMAL_POINTS:-} ]] && SET_ARGS=(--set "segment.max_normal_points=$MAX_NORMAL_POINTS")
for s in "${SCANS[@]}"; do
  name=${s%%=*}; f=${s#*=}
  rm -rf "$OUT/detect/$name"
  for i in $(seq "$REPEATS"); do
    echo "detect: $name (run $i of $REPEATS)"
    "$FH" --graph configs/paper.json "$f" "${SET_ARGS[@]}" --threads "$THREADS" -q --out "$OUT/detect/$name/run$i" >/dev/null
  done
done

# The scannet.json route as a user runs it (issue 21's 50k target: a whole process, model
# cached), on the largest and a small ScanNet dev room: one warm-up run (it trains the model if
# none is cached), then PROCESS_RUNS timed runs each (default 5; the report takes the median).
PROCESS_RUNS=${PROCESS_RUNS:-5}
ROUTE_JSON="$OUT/scannet_route.json"
echo '{"runs": [' >"$ROUTE_JSON"
first=1
for room in scene0000_00 scene0001_01 scene0003_00; do
  f="$SHARED/scannet_votenet50k/$room.ply"
  [[ -f $f ]] || continue
  echo "process: scannet.json on $room ($PROCESS_RUNS runs)"
  "$FH" --graph configs/scannet.json "$f" --threads "$THREADS" -q --out "$OUT/scannet_route/$room" >/dev/null
  for i in $(seq "$PROCESS_RUNS"); do
    t0=$(date +%s%N)
    "$FH" --graph configs/scannet.json "$f" --threads "$THREADS" -q --out "$OUT/scannet_route/$room" >/dev/null
    t1=$(date +%s%N)
    [[ $first == 1 ]] || echo ',' >>"$ROUTE_JSON"
    first=0
    printf '{"room": "%s", "wall_s": %s, "detections": %s}' "$room" "$(awk "BEGIN{print ($t1 - $t0) / 1e9}")" \
      "$(cat "$OUT/scannet_route/$room/detections.json")" >>"$ROUTE_JSON"
  done
done
echo ']}' >>"$ROUTE_JSON"

# What a robot sees from where it stands, as a user runs it (issue 51's targets: a single view in
# 0.3 s, a one-spot laser room of about 50k points in 0.6 s, whole processes, model cached):
# configs/rgbd_view.json on SUN RGB-D dev views (50k points each, camera at the origin) and
# configs/laser_room.json on the 0.1M simulated room (the demo room scanned from its centre at
# 0.25 deg and thinned by a 4 cm voxel filter) and on the demo room itself; one warm-up run
# each, then PROCESS_RUNS timed runs.
VIEWS_JSON="$OUT/views_route.json"
echo '{"runs": [' >"$VIEWS_JSON"
first=1
process_runs() {  # kind graph scan name [args...]
  local kind=$1 graph=$2 f=$3 name=$4
  shift 4
  [[ -f $f ]] || return 0
  echo "process: $graph on $name ($PROCESS_RUNS runs)"
  "$FH" --graph "$graph" "$f" "$@" --threads "$THREADS" -q --out "$OUT/views_route/$name" >/dev/null
  for i in $(seq "$PROCESS_RUNS"); do
    t0=$(date +%s%N)
    "$FH" --graph "$graph" "$f" "$@" --threads "$THREADS" -q --out "$OUT/views_route/$name" >/dev/null
    t1=$(date +%s%N)
    [[ $first == 1 ]] || echo ',' >>"$VIEWS_JSON"
    first=0
    printf '{"kind": "%s", "graph": "%s", "scan": "%s", "wall_s": %s, "detections": %s}' "$kind" "$graph" "$name" \
      "$(awk "BEGIN{print ($t1 - $t0) / 1e9}")" "$(cat "$OUT/views_route/$name/detections.json")" >>"$VIEWS_JSON"
  done
}
for v in sun000001 sun000002 sun000003; do
  process_runs view configs/rgbd_view.json "$SHARED/sunrgbd_dev/$v.ply" "$v" --origin 0,0,0
done
process_runs room configs/laser_room.json "$OUT/rooms/room_0.1M.pcd" room_0.1M
process_runs room configs/laser_room.json data/demo/room.pcd demo_room
echo ']}' >>"$VIEWS_JSON"

# Ours against PCL on the same clouds, in one process (configs/paper.json's radii).
BENCH_ARGS=()
for s in "${SCANS[@]}"; do BENCH_ARGS+=("--scan=$s,paper.json"); done
BENCH_ARGS+=(--ours_iterations="${REPEATS}" --pcl_iterations="${REPEATS}")
[[ -n ${MAX_NORMAL_POINTS:-} ]] && BENCH_ARGS+=(--max_normal_points="$MAX_NORMAL_POINTS")
"$BUILD/bin/bench_region_growing" "${BENCH_ARGS[@]}" --summary_json="$OUT/segmentation.json"

python3 benchmarks/speed/report.py "$OUT" "${DOC_ARGS[@]}"
