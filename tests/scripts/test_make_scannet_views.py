#!/usr/bin/env python3
"""scripts/make_scannet_views.py's camera: what a virtual camera sees (z-buffer of discs, occlusion,
field of view) and how the ground-truth boxes move into its upright frame (stdlib unittest)."""
import importlib.util
import json
import math
import os
import subprocess
import sys
import tempfile
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
spec = importlib.util.spec_from_file_location("make_scannet_views", os.path.join(ROOT, "scripts", "make_scannet_views.py"))
mv = importlib.util.module_from_spec(spec)
spec.loader.exec_module(mv)

SPACING = 0.05


def wall(x, y0, y1, z0, z1, instance):
    """Points of a wall x = const (a grid of SPACING) with an instance id."""
    pts = []
    ny, nz = int(round((y1 - y0) / SPACING)), int(round((z1 - z0) / SPACING))
    for a in range(ny + 1):
        for b in range(nz + 1):
            pts.append((x, y0 + a * SPACING, z0 + b * SPACING, instance))
    return pts


def cloud(parts):
    pts = [p for part in parts for p in part]
    col = {"x": [p[0] for p in pts], "y": [p[1] for p in pts], "z": [p[2] for p in pts], "instance": [p[3] for p in pts]}
    return col, len(pts)


class View(unittest.TestCase):
    def setUp(self):
        # Camera at (0, 0, 1.3) looking along +x. A board (instance 1) 2 m ahead hides the middle
        # of a wider board (instance 2) 3 m ahead; a board behind the camera (instance 3).
        self.col, self.n = cloud([wall(2.0, -0.5, 0.5, 0.5, 1.5, 1), wall(3.0, -1.0, 1.0, 0.5, 1.5, 2),
                                  wall(-2.0, -0.5, 0.5, 0.5, 1.5, 3)])
        self.cam = (0.0, 0.0, 1.3)
        self.seen, self.up = mv.view(self.col, self.n, self.cam, (1.0, 0.0), 2.0 * SPACING)

    def count(self, instance):
        return sum(1 for i in self.seen if self.col["instance"][i] == instance)

    def test_occlusion_and_field_of_view(self):
        total = [sum(1 for v in self.col["instance"] if v == k) for k in (1, 2, 3)]
        self.assertEqual(self.count(3), 0)  # behind the camera
        self.assertGreater(self.count(1), 0.9 * total[0])  # in front, in view
        # The far board's points behind the near board are hidden: only its sides show
        # (the near board covers 1/2 of its width as seen from 3 m, ~2/3 of it at 2 m).
        far = [i for i in self.seen if self.col["instance"][i] == 2]
        self.assertGreater(len(far), 0)
        self.assertLess(len(far), 0.6 * total[1])
        for i in far:
            y = self.col["y"][i]
            self.assertGreater(abs(y), 0.5 * 3.0 / 2.0 - 0.1, f"far point at y = {y} should be hidden")

    def test_upright_frame(self):
        # Looking along +x: forward (y) is the room's x, right (x) is the room's -y, z up from the camera.
        i = next(i for i in self.seen if self.col["instance"][i] == 1 and abs(self.col["y"][i] - 0.5) < 1e-6)
        X, Y, Z = self.up[i]
        self.assertAlmostEqual(Y, 2.0, places=5)
        self.assertAlmostEqual(X, -0.5, places=5)
        self.assertAlmostEqual(Z, self.col["z"][i] - 1.3, places=5)


class BoxInView(unittest.TestCase):
    def test_along_x_swaps_extents(self):
        c, s = mv.box_in_view([2.0, 1.0, 0.5], [0.4, 1.2, 0.9], (0.0, 0.0, 1.3), (1.0, 0.0))
        self.assertEqual([round(v, 6) for v in c], [-1.0, 2.0, -0.8])
        self.assertEqual(s, [1.2, 0.4, 0.9])

    def test_along_minus_y(self):
        # Looking along -y: right is -x; a box at (1, -3) from a camera at (0, 0) is 1 m left, 3 m ahead.
        c, s = mv.box_in_view([1.0, -3.0, 0.5], [0.4, 1.2, 0.9], (0.0, 0.0, 1.3), (0.0, -1.0))
        self.assertEqual([round(v, 6) for v in c], [-1.0, 3.0, -0.8])
        self.assertEqual(s, [0.4, 1.2, 0.9])
        self.assertTrue(math.isclose(c[2], 0.5 - 1.3))


class BadInput(unittest.TestCase):
    """A bad file ends the script with one line naming it and exit 2, never a traceback."""

    def run_on(self, ply_bytes):
        with tempfile.TemporaryDirectory() as d:
            with open(os.path.join(d, "a.ply"), "wb") as f:
                f.write(ply_bytes)
            with open(os.path.join(d, "a.gt.json"), "w") as f:
                json.dump({"objects": []}, f)
            with open(os.path.join(d, "d.json"), "w") as f:
                json.dump({"scenes": [{"scan": "a.ply", "gt": "a.gt.json"}], "classes": ["chair"]}, f)
            r = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "make_scannet_views.py"), "--dataset",
                                os.path.join(d, "d.json"), "--out", os.path.join(d, "out")], capture_output=True, text=True)
        return r

    def test_truncated_and_foreign_files(self):
        header = b"ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty float x\nend_header\n"
        for data, words in ((header + b"abc", "shorter"), (b"junk", "end_header"),
                            (header.replace(b"float x", b"float x\nproperty float y\nproperty float z") + bytes(60),
                             "red")):
            r = self.run_on(data)
            self.assertEqual(r.returncode, 2, r.stderr)
            lines = [l for l in r.stderr.splitlines() if l.strip()]
            self.assertEqual(len(lines), 1, r.stderr)
            self.assertIn("a.ply", lines[0])
            self.assertIn(words, lines[0])


if __name__ == "__main__":
    unittest.main()
