#!/usr/bin/env python3
"""scripts/diagnose_misses.py's causes on a hand-made scene: one chair lost at each step (stdlib unittest)."""
import importlib.util
import os
import sys
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "scripts"))
spec = importlib.util.spec_from_file_location("diagnose_misses", os.path.join(ROOT, "scripts", "diagnose_misses.py"))
dm = importlib.util.module_from_spec(spec)
spec.loader.exec_module(dm)


def box_at(x, half=0.3, top=0.8):
    return ((x - half, -half, 0.0), (x + half, half, top))


def grid_in(box, n=5):
    (x0, y0, z0), (x1, y1, z1) = box
    return [(x0 + (x1 - x0) * (i + 0.5) / n, y0 + (y1 - y0) * (j + 0.5) / n, z0 + (z1 - z0) * (k + 0.5) / n)
            for i in range(n) for j in range(n) for k in range(n)]


def cand(cls, box, score=0.5, verified=True):
    c = [(box[0][k] + box[1][k]) / 2 for k in range(3)]
    return {"cls": cls, "score": score, "verified": verified, "box": box, "center": c, "rejection": ""}


class Causes(unittest.TestCase):
    def test_each_chair_lost_where_it_is(self):
        # Chairs 3 m apart: a0 not proposed at all, a1 proposed only before the NMS, b proposed but
        # fitted nowhere, d fitted as a sofa, c fitted as a chair but refused, ok accepted.
        names = ["a0", "a1", "b", "d", "c", "ok"]
        gboxes = [box_at(3.0 * i) for i in range(len(names))]
        gts = [("chair", b, [(b[0][k] + b[1][k]) / 2 for k in range(3)], 0.3) for b in gboxes]
        pts = [p for b in gboxes for p in grid_in(b)]
        # A proposal of a chair and a much larger one holding it with clutter (not a proposal of it).
        props = [cand("chair", gboxes[i]) for i in (2, 3, 4, 5)]
        clutter = box_at(0.0, half=1.2, top=1.5)
        pts += [p for p in grid_in(clutter, 9) if not dm.inside(p, gboxes[0])]
        props.append(cand("table", clutter))
        allp = props + [cand("chair", gboxes[1])]
        final = [cand("sofa", gboxes[3]), cand("chair", gboxes[4], verified=False), cand("chair", gboxes[5]),
                 cand("chair", box_at(30.0))]
        got = [r[3] for r in dm.scene_causes(pts, gts, final, props, allp, "chair")]
        self.assertEqual(got, names)
        # Without the all-proposals run both unproposed chairs are "a".
        got = [r[3] for r in dm.scene_causes(pts, gts, final, props, None, "chair")]
        self.assertEqual(got[:2], ["a", "a"])

    def test_a_verified_chair_on_the_wrong_object_is_not_ok(self):
        g = box_at(0.0)
        gts = [("chair", g, [0.0, 0.0, 0.4], 0.3)]
        pts = grid_in(g)
        final = [cand("chair", box_at(0.1), score=0.2, verified=False), cand("chair", box_at(5.0), score=0.9)]
        got = dm.scene_causes(pts, gts, final, [cand("chair", g)], None, "chair")
        self.assertEqual(got[0][3], "c")


if __name__ == "__main__":
    unittest.main()
