#!/usr/bin/env python3
"""scripts/loo_grid.py on hand-made detections: each group is scored with the run that does best
on the other groups, never with its own best (stdlib unittest)."""
import importlib.util
import os
import sys
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "scripts"))
spec = importlib.util.spec_from_file_location("loo_grid", os.path.join(ROOT, "scripts", "loo_grid.py"))
lg = importlib.util.module_from_spec(spec)
spec.loader.exec_module(lg)


class FakeDataset:
    """Three scans, one cabinet each: a unit cube at x = 0, 10, 20."""
    def __init__(self):
        self.scenes = [(f"s{k}", [("cabinet", ((10.0 * k, 0.0, 0.0), (10.0 * k + 1, 1.0, 1.0)), (10.0 * k + 0.5, 0.5, 0.5),
                                   0.5)]) for k in range(3)]


def det(k, score, hit):
    x = 10.0 * k + (0.0 if hit else 5.0)
    return (score, "cabinet", ((x, 0.0, 0.0), (x + 1, 1.0, 1.0)), (x + 0.5, 0.5, 0.5))


class HeldOut(unittest.TestCase):
    def test_each_group_takes_the_run_best_elsewhere(self):
        ds = FakeDataset()
        # Run 0 finds the cabinets of s0 and s1, run 1 only that of s2 (and misses s0, s1).
        run0 = {"s0": [det(0, 0.9, True)], "s1": [det(1, 0.8, True)], "s2": [det(2, 0.7, False)]}
        run1 = {"s0": [det(0, 0.9, False)], "s1": [det(1, 0.8, False)], "s2": [det(2, 0.7, True)]}
        group = {"s0": "s0", "s1": "s1", "s2": "s2"}
        ap, chosen = lg.held_out(ds, [run0, run1], group, "cabinet")
        # Every fold's training groups favour run 0 (it finds 1 or 2 of 2, run 1 at most 1 of 2;
        # ties go to the earlier run), so s2 is scored with run 0 and its cabinet is missed.
        self.assertEqual(chosen, [3, 0])
        self.assertAlmostEqual(ap, 2.0 / 3.0, places=6)
        # In sample, run 1 would be s2's best: the held-out figure does not take it.
        ap1, chosen1 = lg.held_out(ds, [run1, run0], group, "cabinet")
        self.assertEqual(chosen1, [0, 3])
        self.assertAlmostEqual(ap1, 2.0 / 3.0, places=6)


if __name__ == "__main__":
    unittest.main()
