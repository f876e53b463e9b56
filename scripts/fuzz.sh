#!/usr/bin/env bash
# Builds the libFuzzer targets (clang, ASan + UBSan) in build-fuzz/ and runs each for a given
# time, starting from the seeds in tests/fuzz/corpus/<target>/ and the corpus grown by earlier
# runs (build-fuzz/fuzz-work/<target>/corpus, minimised after each run). Crashes, leaks and
# slow inputs are copied into tests/fuzz/corpus/<target>/ (crash-*, leak-*, slow-unit-*):
# commit them with the fix, and add the input to tests/hostile/corpus/ with its expectation.
#
#   scripts/fuzz.sh [SECONDS_PER_TARGET=600] [TARGET ...]
#     targets: scan_readers graph_config catalog model_file mesh cli_json (default: all)
#   FUZZ_JOBS=2 scripts/fuzz.sh 600 scan_readers   # two targets at a time ...
#
# Needs clang and libFuzzer (Debian: apt-get install -y clang libclang-rt-14-dev).
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_PER_TARGET=${1:-600}
shift || true
TARGETS=("$@")
[ ${#TARGETS[@]} -eq 0 ] && TARGETS=(scan_readers graph_config catalog model_file mesh cli_json)
BUILD=${FURNIHOST_FUZZ_BUILD_DIR:-build-fuzz}
JOBS=${FUZZ_JOBS:-1}
SAN="-fsanitize=fuzzer-no-link,address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined"

if ! command -v clang++ >/dev/null; then
  echo "fuzz.sh: clang++ not found (apt-get install -y clang libclang-rt-14-dev)" >&2
  exit 2
fi
CC=clang CXX=clang++ cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DFURNIHOST_FUZZ=ON ${FUZZ_CMAKE_ARGS:-} \
  -DFURNIHOST_BUILD_BENCH=OFF -DCMAKE_C_FLAGS="$SAN" -DCMAKE_CXX_FLAGS="$SAN" \
  -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" \
  -DCMAKE_SHARED_LINKER_FLAGS="-fsanitize=address,undefined" \
  -DCMAKE_MODULE_LINKER_FLAGS="-fsanitize=address,undefined" >/dev/null
# Only the targets asked for: fuzz_graph_config and fuzz_cli_json need every plugin built.
cmake --build "$BUILD" $(printf -- '--target fuzz_%s ' "${TARGETS[@]}") -j"${BUILD_JOBS:-2}"

# Libraries the host loads with dlopen (PCL, assimp) are not instrumented: ASan still sees
# their heap through its interceptors. Leaks in them are not ours to fix.
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=1:abort_on_error=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$PWD/tests/fuzz/lsan.supp}

run_one() {
  local t=$1
  local seeds=tests/fuzz/corpus/$t work=$BUILD/fuzz-work/$t
  rm -rf "$work/artifacts"
  mkdir -p "$seeds" "$work/corpus" "$work/artifacts"
  local dict=()
  [ -f "tests/fuzz/$t.dict" ] && dict=(-dict="tests/fuzz/$t.dict")
  local start=$SECONDS
  "$BUILD/bin/fuzz_$t" "$work/corpus" "$seeds" "${dict[@]}" -max_total_time="$SECONDS_PER_TARGET" \
    -timeout=25 -rss_limit_mb=4096 -max_len=65536 -print_final_stats=1 \
    -artifact_prefix="$work/artifacts/" >"$work/log.txt" 2>&1 || true
  # Minimise the grown corpus in place; it stays in the build tree (the committed seeds in
  # tests/fuzz/corpus stay small and hand-made), and the next run starts from it.
  local merged=$work/merged
  rm -rf "$merged" && mkdir -p "$merged"
  "$BUILD/bin/fuzz_$t" -merge=1 "$merged" "$work/corpus" "$seeds" >"$work/merge.txt" 2>&1 || true
  if [ -n "$(ls -A "$merged")" ]; then
    rm -rf "$work/corpus" && mv "$merged" "$work/corpus"
  fi
  local n_found=0
  if [ -n "$(ls -A "$work/artifacts")" ]; then
    # Into the committed seeds: every later run replays them, so a fix stays fixed.
    cp "$work/artifacts"/* "$seeds"/ && n_found=$(ls "$work/artifacts" | wc -l)
  fi
  local execs
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$work/log.txt" | grep -o '[0-9]*$' | tail -1 || true)
  echo "fuzz_$t: $((SECONDS - start)) s, ${execs:-?} runs, corpus $(ls "$work/corpus" | wc -l) files" \
       "($(du -sk --apparent-size "$work/corpus" | cut -f1) KB), findings: $n_found (log: $work/log.txt)"
}

pids=()
for t in "${TARGETS[@]}"; do
  run_one "$t" &
  pids+=($!)
  if [ ${#pids[@]} -ge "$JOBS" ]; then
    wait "${pids[0]}"
    pids=("${pids[@]:1}")
  fi
done
wait
