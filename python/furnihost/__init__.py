"""furnihost: find, name and pose furniture in 3D scans, from Python.

    import furnihost
    g = furnihost.Graph(furnihost.config("scannet.json"))
    points, colors = furnihost.read_scan("scene.ply")
    for d in g.detect(points, colors):
        print(d.class_name, d.score, d.center, d.size, d.yaw, d.accepted)

A graph runs through the engine of the ``furnihost`` command line: the same file gives the same
detections here and in its detections.json. Bad input (a wrong dtype or shape, non-finite rows,
an empty array, a bad graph) raises ValueError with the command line's one-line message.
Open3D is optional: a ``open3d.geometry.PointCloud`` is accepted wherever points are, and
``Detection.to_open3d`` / ``boxes_lineset`` import it when called. See docs/python.md.
"""

import json as _json
import os as _os

import numpy as _np

from . import _furnihost
from ._furnihost import __version__, set_log_level

__all__ = ["Graph", "Detection", "Check", "read_scan", "config", "share_dir", "default_graph", "boxes_lineset",
           "set_log_level", "__version__"]

def class_color(name):
    """The drawing colour of a class, RGB in [0, 1]: the command line's (fitted.ply, votes.png)."""
    return tuple(c / 255.0 for c in _furnihost.class_color(name))


def share_dir():
    """The folder of the shipped graph configs and the bundled catalog (share/furnihost of the
    install prefix, or the source tree of a build)."""
    return _furnihost.share_dir()


def config(name):
    """The path of a shipped graph config, e.g. ``config("scannet.json")``."""
    path = _os.path.join(share_dir(), "configs", name)
    if not _os.path.isfile(path):
        raise ValueError(f"config: {path} does not exist (the shipped configs are in {share_dir()}/configs)")
    return path


def default_graph(has_origin):
    """The graph the command line picks for a scan without --graph: laser_room.json for a scan
    with a sensor origin, room.json for one without."""
    return _furnihost.default_graph(bool(has_origin))


class ScanArrays(tuple):
    """What ``read_scan`` returns: ``(points, colors)``, and the sensor origin as ``.origin``."""

    origin = None


def read_scan(path):
    """Reads a .pcd, .ply or .xyz scan with furnihost's own readers.

    Returns ``(points, colors)``: points float64 (N, 3) in the file's coordinates (non-finite
    points dropped), colors uint8 (N, 3) or None. ``.origin`` of the result is the sensor origin
    the file declares (a PCD's VIEWPOINT), or None.
    """
    points, colors, origin = _furnihost.read_scan(_os.fspath(path))
    result = ScanArrays((points, colors))
    result.origin = origin
    return result


class Check:
    """One verification test of a detection: ``name``, measured ``value``, ``limit``, ``test``
    (">=" or "<=") and whether it ``passed``."""

    __slots__ = ("name", "value", "limit", "test", "passed")

    def __init__(self, record):
        self.name = record["name"]
        self.value = record["value"]
        self.limit = record["limit"]
        self.test = record["test"]
        self.passed = record["passed"]

    def __repr__(self):
        return f"Check({self.name} {self.value!r} {self.test} {self.limit!r}: {'passed' if self.passed else 'failed'})"


class Detection:
    """One detection, in the frame of the points (or file) it was found in.

    class_name  the class ("chair", "table", ...)
    score       the graph's raw score
    confidence  the calibrated probability of being right, when the graph is calibrated (else None)
    accepted    False when a check rejected it, True otherwise
    center      numpy (3,): the detection's centre [m]
    size        numpy (3,): its box's width, depth, height [m] (None without a box)
    yaw         numpy float64: the way it faces [rad, counter-clockwise about up from +x], its
                fitted model's front turned by the model's pose, as detections.json's "yaw"
                (docs/poses.md; "facing" in to_dict() gives it as a direction)
    model       the fitted CAD model's id, or None
    checks      list of Check: what was tested, in order
    """

    def __init__(self, record):
        self._record = record
        self.class_name = record["class"]
        self.score = record["score"]
        self.confidence = record.get("confidence")
        self.accepted = record.get("verified") is not False
        self.center = _np.asarray(record["center"], dtype=_np.float64)
        box = record.get("box")
        self.size = _np.asarray(box["size"], dtype=_np.float64) if box else None
        self.yaw = _np.float64(record["yaw"])
        self.model = record.get("model")
        self.checks = [Check(c) for c in record.get("checks", [])]

    def to_dict(self):
        """The detection's entry of detections.json (a deep copy)."""
        return _json.loads(_json.dumps(self._record))

    def to_open3d(self):
        """Its box as an ``open3d.geometry.OrientedBoundingBox`` (coloured by class)."""
        import open3d as o3d

        box = self._record.get("box")
        if not box:
            raise ValueError(f"to_open3d: this {self.class_name} detection has no box")
        rotation = _np.asarray(box["axes"], dtype=_np.float64).T  # columns: the box's axes
        obb = o3d.geometry.OrientedBoundingBox(_np.asarray(box["center"], dtype=_np.float64), rotation,
                                               _np.asarray(box["size"], dtype=_np.float64))
        obb.color = class_color(self.class_name)
        return obb

    def __repr__(self):
        c = ", ".join(f"{v:.2f}" for v in self.center)
        state = "accepted" if self.accepted else "rejected"
        return f"Detection({self.class_name} at ({c}), score {self.score:.3f}, {state}, model {self.model})"


def boxes_lineset(detections):
    """The boxes of ``detections`` as one ``open3d.geometry.LineSet`` (12 edges each, coloured by
    class), to draw over the cloud."""
    import open3d as o3d

    lines = o3d.geometry.LineSet()
    for d in detections:
        if d.size is None:
            continue
        box = o3d.geometry.LineSet.create_from_oriented_bounding_box(d.to_open3d())
        box.paint_uniform_color(class_color(d.class_name))
        lines += box
    return lines


def _is_open3d_cloud(points):
    return type(points).__module__.startswith("open3d") and hasattr(points, "points") and hasattr(points, "has_colors")


class Graph:
    """A graph config loaded and validated, its plugins created: run it many times.

    ``Graph(path, set={"recognise.sig_profile": 0.1})``: ``set`` changes parameters as the
    command line's ``--set TAG.PARAM=VALUE`` (a value is any JSON value). ``plugin_path``: extra
    plugin folders (``--plugin-path``); ``seed``: the detection seed (default: the graph's);
    ``strict``: invalid catalog entries are errors; ``retrain``: train even when the model
    cache is valid. The catalog and the model (the cache, or trained) start loading on a worker
    at once; an error of theirs (a bad catalog) is raised by the first train, detect or evaluate.
    One call at a time per Graph; the GIL is released while it works.
    """

    def __init__(self, path, set=None, *, plugin_path=(), seed=None, strict=False, retrain=False):
        sets = []
        for key, value in (set or {}).items():
            sets.append(f"{key}={_json.dumps(value)}")
        if isinstance(plugin_path, (str, _os.PathLike)):
            plugin_path = [plugin_path]
        self._graph = _furnihost.Graph(_os.fspath(path), sets, [_os.fspath(p) for p in plugin_path], seed, strict,
                                       retrain)

    @property
    def path(self):
        """The graph config's path."""
        return self._graph.path

    @property
    def config(self):
        """The resolved config: every stage with every parameter (defaults filled)."""
        return self._graph.config

    @property
    def seed(self):
        return self._graph.seed

    def train(self):
        """Trains the model from the graph's catalog now and writes its cache (unless this Graph
        has just trained it, its cache missing or stale); returns the training summary (models;
        per voter by stage tag its views and parts, per class; time per stage)."""
        return self._graph.train()

    def run(self, points, colors=None, origin=None, up="+z", transform=None):
        """Detects in one scan and returns the whole detections.json document (dict): the frame,
        the ground, every detection, the time per stage. Arguments as ``detect``."""
        if _is_open3d_cloud(points):
            cloud = points
            points = _np.asarray(cloud.points)
            if colors is None and cloud.has_colors():
                colors = _np.asarray(cloud.colors)
        elif isinstance(points, _os.PathLike):
            points = _os.fspath(points)
        return self._graph.detect(points, colors, origin, up, transform)

    def detect(self, points, colors=None, origin=None, up="+z", transform=None):
        """Detects furniture in one scan; returns a list of Detection, best first as the graph
        sorts them.

        points     numpy (N, 3) float32 or float64 [m], an ``open3d.geometry.PointCloud``, or
                   the path of a .pcd / .ply / .xyz file (read as the command line reads it)
        colors     None, or (N, 3) uint8 or float in [0, 1] (a PointCloud's are taken)
        origin     the sensor origin (x, y, z) in the points' frame, or None (--origin)
        up         which axis points up: "+z" (default), "-y" (a camera's optical frame), ...,
                   or "auto" (--up)
        transform  points -> z-up frame: a 4x4 matrix, or (x, y, z, roll, pitch, yaw)
                   (--transform; instead of up)
        """
        doc = self.run(points, colors, origin, up, transform)
        return [Detection(d) for d in doc["detections"]]

    def evaluate(self, dataset, *, seeds=1, width="max", jobs=0, jitter=0.0, name=""):
        """Runs the graph over a dataset manifest (benchmarks/*.json) and matches its detections
        with the ground truth: the dict ``furnihost eval`` writes as summary.json (without its
        git and machine records). Per class: AP by the paper's rule and at box IoU 0.25 / 0.5,
        and the precision-recall curves (``configs[0]["runs"][0]["metrics"]["classes"]``)."""
        return self._graph.evaluate(_os.fspath(dataset), int(seeds), width, int(jobs), float(jitter), name)

    def __repr__(self):
        return f"furnihost.Graph({self.path!r})"
