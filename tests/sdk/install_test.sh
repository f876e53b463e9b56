#!/usr/bin/env bash
# The installable SDK: `cmake --install BUILD --prefix P` into a temporary prefix gives
#   - a binary that finds its plugins (P's, never the build tree's), configs and bundled catalog
#     with no environment variable, and detects in the installed demo room with no flag (the
#     default graph of a scan with a sensor origin, its model cached under P);
#   - a CMake package: a plugin project outside the tree (tests/sdk/outside_plugin: a few lines)
#     builds against P with furnihost_add_plugin, its test passes, and the installed binary
#     lists it with --plugin-path;
#   - the Python package, which finds the same share folder and plugins.
#   tests/sdk/install_test.sh BUILD_DIR SOURCE_DIR PYTHON
set -euo pipefail
BUILD=$(cd "$1" && pwd)
SOURCE=$(cd "$2" && pwd)
PYTHON=${3:-python3}
TMP=$(mktemp -d "${TMPDIR:-/tmp}/furnihost_sdk.XXXXXX")
trap 'rm -rf "$TMP"' EXIT
P=$TMP/prefix
fail() { echo "install_test: FAIL: $*" >&2; exit 1; }
# Nothing may come from the environment or the build tree.
unset FURNIHOST_PLUGIN_PATH FURNIHOST_SOURCE_DIR PYTHONPATH
cd "$TMP"

cmake --install "$BUILD" --prefix "$P" >install.log
for f in bin/furnihost lib/libfurnihost_sdk.so lib/libfurnihost_host.so lib/cmake/furnihost/furnihostConfig.cmake \
         lib/cmake/furnihost/FurnihostPlugin.cmake share/furnihost/configs/laser_room.json \
         share/furnihost/configs/room.json share/furnihost/data/catalog/catalog.json share/furnihost/data/demo/room.pcd \
         include/furnihost/plugin.hpp; do
  [ -e "$P/$f" ] || fail "$f not installed"
done
ls "$P"/lib/furnihost/plugins/libfurnihost_sensor_scan_file.so >/dev/null || fail "no plugins installed"

# The shipped plugins, from the prefix.
"$P/bin/furnihost" plugins --json >plugins.json
"$PYTHON" - "$P" <<'EOF' || fail "the installed binary's plugins"
import json, sys
prefix = sys.argv[1]
plugins = json.load(open("plugins.json"))
entries = plugins["plugins"] if isinstance(plugins, dict) else plugins
paths = [p["path"] for p in entries]
assert len(paths) >= 15, paths
bad = [p for p in paths if not p.startswith(prefix + "/lib/furnihost/plugins/")]
assert not bad, f"plugins loaded from outside the prefix: {bad}"
EOF

# The graphs' relative catalog paths resolve inside the prefix.
for g in laser_room room paper; do
  "$P/bin/furnihost" validate --graph "$P/share/furnihost/configs/$g.json" --print >"$g.resolved" ||
    fail "$g.json does not validate"
  "$PYTHON" -c "
import json, os, sys
text = open('$g.resolved').read()
j = json.loads(text[text.index('{'):])
assert j['catalog'].startswith('$P/share/furnihost/data/catalog/') and os.path.isfile(j['catalog']), j['catalog']
" || fail "$g.json's catalog does not resolve inside the prefix"
done

# An out-of-tree plugin: configure, build and test it against the prefix only.
cmake -S "$SOURCE/tests/sdk/outside_plugin" -B outside -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$P" \
  -DGRID_SOURCE="$SOURCE/examples/plugins/grid_segmenter/grid_segmenter.cpp" >outside_configure.log 2>&1 ||
  { cat outside_configure.log; fail "the out-of-tree plugin does not configure"; }
cmake --build outside -j2 >outside_build.log 2>&1 || { tail -30 outside_build.log; fail "the out-of-tree plugin does not build"; }
[ -f outside/plugins/libfurnihost_segmenter_example_grid.so ] || fail "no plugin library in outside/plugins"
(cd outside && ctest --output-on-failure) >outside_test.log 2>&1 || { cat outside_test.log; fail "its test fails"; }
grep -q "1 tests passed\|100% tests passed" outside_test.log || fail "its test did not run"
"$P/bin/furnihost" plugins >plugins_without.txt
if grep -q "segmenters.example_grid" plugins_without.txt; then fail "the plugin is listed without --plugin-path"; fi
"$P/bin/furnihost" plugins --plugin-path outside/plugins >plugins_with.txt
grep -q "segmenters.example_grid" plugins_with.txt || { cat plugins_with.txt; fail "the installed binary does not list it"; }

# No flag but the scan: the installed demo room has a sensor origin (VIEWPOINT): laser_room.json.
"$P/bin/furnihost" "$P/share/furnihost/data/demo/room.pcd" --out demo >demo.out 2>demo.err ||
  { tail -5 demo.err; fail "the installed binary does not detect in the demo room"; }
grep "no --graph" demo.err | grep -q "$P/share/furnihost/configs/laser_room.json" ||
  { cat demo.err; fail "no log line naming the default graph"; }
[ -f "$P/share/furnihost/furnihost-out/models/laser_room.fhm" ] || fail "the model cache is not under the prefix"
"$PYTHON" -c "
import json
d = json.load(open('demo/detections.json'))['detections']
assert sum(1 for x in d if x['verified']) >= 4, [(x['class'], x['verified']) for x in d]
" || fail "the installed binary's detections in the demo room"

# The Python package of the prefix: its share folder and plugins, the same detections.
site=$(ls -d "$P"/lib/python3*/*-packages)
PYTHONPATH=$site "$PYTHON" - "$P" <<'EOF' || fail "the installed Python package"
import json, sys
import furnihost
prefix = sys.argv[1]
assert furnihost.__file__.startswith(prefix), furnihost.__file__
assert furnihost.share_dir() == prefix + "/share/furnihost", furnihost.share_dir()
assert furnihost.default_graph(True) == prefix + "/share/furnihost/configs/laser_room.json"
arrays = furnihost.read_scan(prefix + "/share/furnihost/data/demo/room.pcd")
g = furnihost.Graph(furnihost.config("laser_room.json"))
ours = g.run(arrays[0], arrays[1], origin=arrays.origin)["detections"]
assert ours == json.load(open("demo/detections.json"))["detections"]
EOF
echo "install_test: the installed binary, plugins, configs, catalog, CMake package and Python package work from $P"
