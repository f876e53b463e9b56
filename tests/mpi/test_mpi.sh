#!/usr/bin/env bash
# furnihost under mpirun (framework/app/mpi_jobs.hpp), run by ctest (tests/CMakeLists.txt):
#   test_mpi.sh FURNIHOST MPIEXEC SOURCE_DIR WORK_DIR CASE
# CASE:
#   eval    `mpirun -n 2` eval of benchmarks/scannet_dev.json (configs/scannet.json, one thread a
#           rank) writes summary.json, report.md and run_scannet.json byte for byte as one process
#           (both with --reproducible: the run's own times, memory and host left out).
#   train   `mpirun -n 2` training of configs/scannet.json (the 38 models of the shared catalog,
#           each rank's voter learning a run of them, merged on rank 0) writes the one process's
#           model file byte for byte; the same for configs/paper.json (the bundled catalog scanned
#           by both ranks, its vocabulary learned on rank 0).
#   cv      `mpirun -n 2` scripts/cross_validate.py (python3-mpi4py) on 6 ScanNet dev scans of 3
#           spaces, grid "tiny": the same stdout and heldout.json as one process.
#   failure a scene that cannot be read, taken by a rank: exit 2, the error names the rank, its host
#           and the job, and no output folder is left.
#   death   rank 1 killed (SIGKILL) while the ranks hold jobs: mpirun ends the run, rank 0 names
#           the job each rank held and the rank that died, and no output folder is left.
set -uo pipefail
FH=$1 MPIEXEC=$2 SRC=$3 WORK=$4 CASE=$5
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
MPI=("$MPIEXEC" -n 2)
DATA="$SRC/benchmarks/scannet_dev.json"
rm -rf "$WORK/$CASE" && mkdir -p "$WORK/$CASE" && cd "$WORK/$CASE" || exit 1
fail() { echo "FAIL: $*" >&2; exit 1; }

case "$CASE" in
eval)
  "$FH" eval --graph "$SRC/configs/scannet.json" --dataset "$DATA" --out one --reproducible -q --threads 2 >one.log 2>&1 ||
    fail "one process: $(tail -3 one.log)"
  "${MPI[@]}" "$FH" eval --graph "$SRC/configs/scannet.json" --dataset "$DATA" --out two --reproducible -q --threads 1 \
    >two.log 2>&1 || fail "two ranks: $(tail -3 two.log)"
  for f in summary.json report.md run_scannet.json; do
    cmp one/$f two/$f || fail "$f differs between one process and two ranks"
  done
  grep -q '"ap25"' two/summary.json || fail "no figures in summary.json"
  ;;
train)
  "$FH" train --graph "$SRC/configs/scannet.json" --out one.fhm -q --threads 2 >one.log 2>&1 || fail "one process: $(tail -3 one.log)"
  "${MPI[@]}" "$FH" train --graph "$SRC/configs/scannet.json" --out two.fhm --threads 1 >two.log 2>&1 ||
    fail "two ranks: $(tail -3 two.log)"
  cmp one.fhm two.fhm || fail "the model files differ"
  grep -q "in 2 runs of consecutive models" two.log || fail "the ranks did not share the voter's work: $(cat two.log)"
  # paper.json: the bundled catalog scanned by the ranks, its vocabulary (which does not merge)
  # learned on rank 0 from every model's views.
  "$FH" train --graph "$SRC/configs/paper.json" --out paper_one.fhm -q --threads 2 >paper_one.log 2>&1 ||
    fail "paper.json, one process: $(tail -3 paper_one.log)"
  "${MPI[@]}" "$FH" train --graph "$SRC/configs/paper.json" --out paper_two.fhm --threads 1 >paper_two.log 2>&1 ||
    fail "paper.json, two ranks: $(tail -3 paper_two.log)"
  cmp paper_one.fhm paper_two.fhm || fail "paper.json: the model files differ"
  grep -q "scanning models (rank 1)" paper_two.log || fail "paper.json: rank 1 scanned no model: $(cat paper_two.log)"
  ! grep -q "runs of consecutive models" paper_two.log || fail "paper.json's vocabulary was merged from runs"
  ;;
cv)
  python3 - "$DATA" six.json <<'PY' || fail "manifest"
import json, os, sys
d = json.load(open(sys.argv[1]))
base = os.path.dirname(os.path.abspath(sys.argv[1]))
keep = [s for s in d["scenes"] if any(k in s["scan"] for k in ("scene0000_0", "scene0001_0", "scene0002_0"))]
for s in keep:
    s["scan"], s["gt"] = os.path.join(base, s["scan"]), os.path.join(base, s["gt"])
d["scenes"] = keep
json.dump(d, open(sys.argv[2], "w"))
PY
  CV=("$SRC/scripts/cross_validate.py" --graph "$SRC/configs/scannet.json" --dataset six.json --grid tiny --furnihost "$FH")
  "${PYTHON:-python3}" "${CV[@]}" --out one --threads 2 >one.out 2>one.err || fail "one process: $(tail -3 one.err)"
  "${MPI[@]}" "${PYTHON:-python3}" "${CV[@]}" --out two --threads 1 >two.out 2>two.err || fail "two ranks: $(tail -3 two.err)"
  cmp one.out two.out || fail "stdout differs"
  cmp one/heldout.json two/heldout.json || fail "heldout.json differs"
  grep -q "2 ranks" two.err || fail "the two ranks did not share the work (mpi4py missing?)"
  ;;
failure)
  printf 'ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n' >broken.ply
  echo '{"objects": []}' >broken.gt.json
  python3 - "$DATA" bad.json <<'PY' || fail "manifest"
import json, os, sys
d = json.load(open(sys.argv[1]))
base = os.path.dirname(os.path.abspath(sys.argv[1]))
scenes = d["scenes"][:3]
for s in scenes:
    s["scan"], s["gt"] = os.path.join(base, s["scan"]), os.path.join(base, s["gt"])
# Every job but the first is the broken scan: whichever rank takes one fails.
d["scenes"] = scenes[:1] + [{"scan": "broken.ply", "gt": "broken.gt.json"}] * 4
json.dump(d, open(sys.argv[2], "w"))
PY
  "${MPI[@]}" "$FH" eval --graph "$SRC/configs/scannet.json" --dataset bad.json --out out -q --threads 1 >log 2>&1
  rc=$?
  [[ $rc == 2 ]] || fail "exit code $rc, expected 2: $(cat log)"
  grep -q "broken.ply" log || fail "the error does not name the scan: $(cat log)"
  if grep -q "furnihost: error: rank 1 (" log; then
    grep -Eq "furnihost: error: rank 1 \([^)]*\): job [0-9]+ of 5 \(scene [^)]*broken.ply, seed 42, config scannet\)" log ||
      fail "the error does not name the rank and the job: $(cat log)"
  fi
  [[ ! -e out ]] || fail "the failed run left $(ls out)"
  ;;
death)
  # The model cached first (one process, one scene), so that the ranks reach the scenes at once.
  python3 - "$DATA" one.json <<'PY' || fail "manifest"
import json, os, sys
d = json.load(open(sys.argv[1]))
base = os.path.dirname(os.path.abspath(sys.argv[1]))
d["scenes"] = d["scenes"][:1]
for s in d["scenes"]:
    s["scan"], s["gt"] = os.path.join(base, s["scan"]), os.path.join(base, s["gt"])
json.dump(d, open(sys.argv[2], "w"))
PY
  "$FH" eval --graph "$SRC/configs/scannet.json" --dataset one.json --out warm -q --threads 2 >warm.log 2>&1 ||
    fail "warm-up: $(tail -3 warm.log)"
  # Rank 1 kills itself 2 s after it starts: it then holds a job (the 54 jobs of 3 seeds take
  # longer than that).
  "${MPI[@]}" bash -c 'if [[ $OMPI_COMM_WORLD_RANK == 1 ]]; then (sleep 2; kill -9 $$) & fi; exec "$0" "$@"' \
    "$FH" eval --graph "$SRC/configs/scannet.json" --dataset "$DATA" --seeds 3 --out out -q --threads 1 >log 2>&1
  rc=$?
  [[ $rc != 0 ]] || fail "the run succeeded though rank 1 died"
  grep -q "rank 0 stopped by signal" log || fail "rank 0 did not say which jobs the ranks held: $(cat log)"
  grep -Eq "rank 1 \([^)]*, pid [0-9]+\): died holding job [0-9]+ of 54 \(scene .*scene0.*\.ply, seed 4[234], config scannet\)" log ||
    fail "the rank that died and its job are not named: $(cat log)"
  [[ ! -e out ]] || fail "the failed run left $(ls out)"
  ;;
*) fail "unknown case $CASE" ;;
esac
echo "PASS: $CASE"
