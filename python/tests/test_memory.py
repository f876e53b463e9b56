"""10,000 detections on a 5k-point cloud leave the resident memory flat (within 5 MB): nothing of
a run (the scan, its frame, the detections, their Python objects) outlives it. A fast graph:
the example plugins of docs/writing-a-plugin.md (grid segmenter, centroid features, class-mean
voter, score fitter) with a level ground and the scan's own frame (the canonical frame's and the
height map's searches would be most of the time), on 5000 points of the demo room."""

import json
import os
import pathlib
import time

import numpy as np

import furnihost
from conftest import SOURCE

CALLS = 10_000
WARM_UP = 500


def resident_mb():
    for line in pathlib.Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    raise AssertionError("no VmRSS in /proc/self/status")


def test_ten_thousand_detections_leave_memory_flat(tmp_path):
    build = pathlib.Path(os.environ.get("FURNIHOST_BUILD_DIR", SOURCE / "build"))
    graph = tmp_path / "fast.json"
    graph.write_text(json.dumps({"extends": str(SOURCE / "examples" / "plugins" / "examples.json"),
                                 "frame": {"canonical": False}, "ground": {"kind": "level"}}))
    g = furnihost.Graph(graph, plugin_path=[build / "examples" / "plugins"])
    points, colors = furnihost.read_scan(SOURCE / "data" / "demo" / "room.pcd")
    keep = np.random.default_rng(3).choice(len(points), 5000, replace=False)
    points = np.ascontiguousarray(points[np.sort(keep)])
    first = g.detect(points)
    assert first, "vacuous: no detection to build Python objects of"
    start = time.perf_counter()
    for _ in range(WARM_UP):
        dets = g.detect(points)
    before = resident_mb()
    for _ in range(CALLS - WARM_UP):
        dets = g.detect(points)
    after = resident_mb()
    seconds = time.perf_counter() - start
    print(f"{CALLS} detections of {len(points)} points in {seconds:.1f} s; resident {before:.1f} -> {after:.1f} MB")
    assert [d.to_dict() for d in dets] == [d.to_dict() for d in first]  # the same work every time
    assert after - before <= 5.0, f"resident memory grew {after - before:.1f} MB over {CALLS - WARM_UP} detections"
