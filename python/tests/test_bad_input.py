"""Bad input raises ValueError with a one-line message naming what is wrong (the command line's
message where the command line has the same input), never a crash; the graph stays usable."""

import json

import numpy as np
import pytest

import furnihost
from conftest import SOURCE

SCANNET = str(SOURCE / "configs" / "scannet.json")


@pytest.fixture(scope="module")
def graph():
    return furnihost.Graph(SCANNET)


def cloud(n=1000, dtype=np.float64):
    rng = np.random.default_rng(1)
    return (rng.random((n, 3)) * [4.0, 3.0, 2.5]).astype(dtype)


def raises(fn, *needles):
    with pytest.raises(ValueError) as e:
        fn()
    message = str(e.value)
    assert "\n" not in message and message, message
    for needle in needles:
        assert needle in message, message
    return message


NAN_ROW = cloud()
NAN_ROW[17, 1] = np.nan
INF_ROW = cloud(dtype=np.float32)
INF_ROW[3] = np.inf

BAD_POINTS = [
    (cloud().astype(np.int64), ("points:", "float32 or float64", "int64")),
    (cloud().astype(np.float16), ("points:", "float16")),
    (cloud()[:, :2], ("points:", "shape (N, 3)", "(1000, 2)")),
    (cloud().reshape(1000, 3, 1), ("points:", "(1000, 3, 1)")),
    (cloud().ravel(), ("points:", "(3000,)")),
    (np.zeros((0, 3)), ("points:", "empty")),
    (NAN_ROW, ("points:", "row 17", "not finite", "1 of 1000 rows")),
    (INF_ROW, ("points:", "row 3", "not finite")),
    (cloud().tolist(), ("points:", "numpy array", "list")),
    (None, ("points:", "NoneType")),
]


@pytest.mark.parametrize("points,needles", BAD_POINTS, ids=[n[1] if len(n) > 1 else n[0] for _, n in BAD_POINTS])
def test_bad_points(graph, points, needles):
    raises(lambda: graph.detect(points), *needles)


def test_bad_arguments(graph):
    pts = cloud()
    raises(lambda: graph.detect(pts, colors=np.zeros((999, 3), np.uint8)), "colors:", "(1000, 3)")
    raises(lambda: graph.detect(pts, colors=np.full((1000, 3), 2.0)), "colors:", "[0, 1]")
    raises(lambda: graph.detect(pts, colors=np.zeros((1000, 3), np.int32)), "colors:", "int32")
    raises(lambda: graph.detect(pts, origin=[1, 2]), "origin:", "3 numbers")
    raises(lambda: graph.detect(pts, origin=[1, 2, np.nan]), "origin:", "not finite")
    raises(lambda: graph.detect(pts, up="sideways"), "up:", "'sideways' is not an axis")
    raises(lambda: graph.detect(pts, transform=np.eye(3)), "transform:", "16 numbers")
    scaled = np.eye(4)
    scaled[:3, :3] *= 2.0
    raises(lambda: graph.detect(pts, transform=scaled), "transform:", "not a rotation")
    raises(lambda: graph.detect(pts, transform=[0, 0, 0, 0, 0, np.inf]), "transform:", "not finite")
    raises(lambda: graph.detect(pts, up="-y", transform=np.eye(4)), "transform:", "not both")
    raises(lambda: graph.detect(str(SOURCE / "no_such_scan.ply")), "no_such_scan.ply")
    raises(lambda: graph.detect(str(SOURCE / "configs")), "configs: is a directory")
    raises(lambda: graph.evaluate(SOURCE / "no_such_dataset.json"), "no_such_dataset.json")
    raises(lambda: graph.evaluate(SOURCE / "benchmarks" / "demo.json", width="wide"), "width:")
    # After all that the graph still detects.
    assert isinstance(graph.detect(pts), list)


def test_bad_graphs(tmp_path):
    raises(lambda: furnihost.Graph(tmp_path / "missing.json"), "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"extends": SCANNET, "stages": {"recognise": {"params": {"sig_profile": "wide"}}}}))
    raises(lambda: furnihost.Graph(bad), "bad.json", "/stages/recognise/params/sig_profile")
    unknown = tmp_path / "unknown.json"
    unknown.write_text(json.dumps({"extends": SCANNET, "stages": {"recognise": {"type": "voters.nope"}}}))
    raises(lambda: furnihost.Graph(unknown), "unknown.json", "voters.nope")
    raises(lambda: furnihost.Graph(SCANNET, set={"recognise.no_such_param": 1}), "--set", "no_such_param")
    raises(lambda: furnihost.Graph(SCANNET, set={"nostage.x": 1}), "--set", "nostage")
    truncated = tmp_path / "truncated.json"
    truncated.write_text('{"stages": {')
    raises(lambda: furnihost.Graph(truncated), "truncated.json")


def test_the_message_is_the_command_lines(tmp_path):
    """A graph error reads as the command line prints it after 'furnihost: error: '."""
    from conftest import run_cli

    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"extends": SCANNET, "stages": {"recognise": {"params": {"sig_profile": -1}}}}))
    message = raises(lambda: furnihost.Graph(bad), "bad.json")
    r = run_cli("validate", "--graph", bad, check=False)
    assert r.returncode == 2
    assert f"furnihost: error: {message}" in r.stderr.splitlines()


def test_a_bad_scan_file_reads_as_on_the_command_line(graph, tmp_path):
    from conftest import run_cli

    scan = tmp_path / "broken.pcd"
    scan.write_text("VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 5\nHEIGHT 1\nPOINTS 9\nDATA ascii\n")
    message = raises(lambda: graph.detect(str(scan)), "broken.pcd")
    assert raises(lambda: furnihost.read_scan(scan), "broken.pcd") in message
    r = run_cli("--graph", SCANNET, "--out", tmp_path / "out", scan, check=False)
    assert r.returncode == 2
    assert f"furnihost: error: {message}" in r.stderr.splitlines()
