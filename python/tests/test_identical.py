"""Python and the command line give the same detections of the same scan: two ScanNet dev rooms
(room reconstructions, scannet.json) and the bundled demo room (a laser scan with a sensor origin,
laser_room.json: the fitter and its free-space check run), each as numpy arrays from read_scan,
as the file's path, and through the command line's detections.json."""

import numpy as np
import pytest

import furnihost
from conftest import SOURCE, cli_detections, shared_file

SCANNET = str(SOURCE / "configs" / "scannet.json")
LASER = str(SOURCE / "configs" / "laser_room.json")


@pytest.fixture(scope="module")
def scannet():
    return furnihost.Graph(SCANNET)


@pytest.mark.parametrize("scene", ["scene0001_00", "scene0002_00"])
def test_scannet_rooms_identical(scannet, scene, out_dir):
    scan = shared_file("scannet_votenet50k", f"{scene}.ply")
    cli = cli_detections(scan, SCANNET, out_dir)
    assert cli["detections"], "vacuous: the command line found nothing"
    points, colors = furnihost.read_scan(scan)
    assert points.dtype == np.float64 and points.shape == (50000, 3) and colors.shape == (50000, 3)
    doc = scannet.run(points, colors)
    assert doc["detections"] == cli["detections"]
    for key in ("points", "frames", "ground", "stages_run", "seed"):
        assert doc[key] == cli[key], key
    # float32 input, and the path itself, the same.
    assert scannet.run(points.astype(np.float32))["detections"] == cli["detections"]
    dets = scannet.detect(str(scan))
    assert [d.to_dict() for d in dets] == cli["detections"]
    accepted = [d for d in dets if d.accepted]
    assert accepted, "no accepted detection to compare"
    for d, entry in zip(dets, cli["detections"]):
        assert d.class_name == entry["class"] and d.score == entry["score"]
        assert d.accepted == (entry["verified"] is not False)
        np.testing.assert_array_equal(d.center, entry["center"])
        np.testing.assert_array_equal(d.size, entry["box"]["size"])
        assert d.yaw == entry["yaw"] and d.model == entry["model"]
        assert [(c.name, c.value, c.limit, c.passed) for c in d.checks] == [
            (c["name"], c["value"], c["limit"], c["passed"]) for c in entry.get("checks", [])]


def test_demo_room_with_its_sensor_origin_identical(out_dir):
    scan = SOURCE / "data" / "demo" / "room.pcd"
    cli = cli_detections(scan, LASER, out_dir)
    assert any(d["verified"] for d in cli["detections"]), "vacuous: nothing accepted in the demo room"
    arrays = furnihost.read_scan(scan)
    points, colors = arrays
    np.testing.assert_array_equal(arrays.origin, [3.0, 2.5, 1.5])  # the PCD's VIEWPOINT
    g = furnihost.Graph(LASER)
    assert g.run(points, colors, origin=arrays.origin)["detections"] == cli["detections"]
    # Without the origin the free-space check cannot run: not the same run.
    assert g.run(points)["detections"] != cli["detections"]
