#!/usr/bin/env python3
"""scripts/cross_validate.py's matching and AP rules on hand-worked cases (stdlib unittest).

The figures the script reports come from these functions; each case below is worked out by hand
so a change in the rules (VoteNet's IoU matching, the paper's centre rule, VOC all-point AP, the
operating threshold) fails here first."""
import importlib.util
import os
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
spec = importlib.util.spec_from_file_location("cross_validate", os.path.join(ROOT, "scripts", "cross_validate.py"))
cv = importlib.util.module_from_spec(spec)
spec.loader.exec_module(cv)


def box(cx, cy, cz, sx, sy, sz):
    return ((cx - sx / 2, cy - sy / 2, cz - sz / 2), (cx + sx / 2, cy + sy / 2, cz + sz / 2))


class BoxIou(unittest.TestCase):
    def test_cases(self):
        a = box(0, 0, 0, 1, 1, 1)
        self.assertAlmostEqual(cv.box_iou(a, a), 1.0)
        # Shifted by half a side in x: overlap 0.5, union 1.5.
        self.assertAlmostEqual(cv.box_iou(a, box(0.5, 0, 0, 1, 1, 1)), 1 / 3)
        self.assertEqual(cv.box_iou(a, box(2, 0, 0, 1, 1, 1)), 0.0)
        # A box inside another: the small volume over the large.
        self.assertAlmostEqual(cv.box_iou(a, box(0, 0, 0, 0.5, 0.5, 0.5)), 0.125)


class MatchScene(unittest.TestCase):
    gts = [("chair", box(0, 0, 0.4, 0.6, 0.6, 0.8), (0, 0, 0.4), 0.3),
           ("chair", box(2, 0, 0.4, 0.6, 0.6, 0.8), (2, 0, 0.4), 0.3)]

    def test_iou_rule_takes_each_truth_once_and_only_of_its_class(self):
        dets = [(0.9, "chair", box(0.05, 0, 0.4, 0.6, 0.6, 0.8), (0.05, 0, 0.4)),   # TP (IoU 0.85)
                (0.8, "chair", box(0.1, 0, 0.4, 0.6, 0.6, 0.8), (0.1, 0, 0.4)),     # same truth again: FP
                (0.7, "table", box(2, 0, 0.4, 0.6, 0.6, 0.8), (2, 0, 0.4)),         # wrong class: FP
                (0.6, "chair", box(2.4, 0, 0.4, 0.6, 0.6, 0.8), (2.4, 0, 0.4))]     # IoU 0.2/1.0 = 0.2 < 0.25
        self.assertEqual(cv.match_scene(dets, self.gts, "iou", 0.25), [True, False, False, False])
        # At IoU >= 0.1 the last one matches the second chair.
        self.assertEqual(cv.match_scene(dets, self.gts, "iou", 0.1), [True, False, False, True])

    def test_paper_rule_is_the_centre_within_the_radius(self):
        dets = [(0.5, "chair", box(0.25, 0, 0.4, 3, 3, 3), (0.25, 0, 0.4)),  # any box: centre 0.25 < 0.3
                (0.9, "chair", box(2.35, 0, 0.4, 0.6, 0.6, 0.8), (2.35, 0, 0.4))]  # 0.35 > 0.3
        self.assertEqual(cv.match_scene(dets, self.gts, "paper"), [True, False])


class AveragePrecision(unittest.TestCase):
    def test_voc_all_point(self):
        # Ranked TP, FP, TP with 2 truths: points (0.5, 1), (0.5, 0.5), (1, 2/3); interpolated
        # precision 1 up to recall 0.5 then 2/3: AP = 0.5 + 0.5 * 2/3.
        self.assertAlmostEqual(cv.average_precision([(0.9, True), (0.8, False), (0.7, True)], 2), 0.5 + 1 / 3)
        # A missed truth caps recall.
        self.assertAlmostEqual(cv.average_precision([(0.9, True)], 4), 0.25)
        # Tied scores make one point: TP and FP at 0.9 give precision 0.5 at recall 1.
        self.assertAlmostEqual(cv.average_precision([(0.9, True), (0.9, False)], 1), 0.5)
        self.assertTrue(cv.average_precision([], 0) != cv.average_precision([], 0))  # NaN without truths

    def test_operating_threshold(self):
        scored = [(0.9, True), (0.8, True), (0.7, False), (0.6, True), (0.5, False), (0.4, False)]
        # Running precision: 1, 1, 2/3, 3/4, 3/5, 1/2: the lowest score with >= 0.75 is 0.6.
        self.assertEqual(cv.operating_threshold(scored, 3), 0.6)
        # Never precise enough (1/2 at most): the score of best F1, 0.5 (P 1/2, R 1).
        self.assertEqual(cv.operating_threshold([(0.9, False), (0.5, True)], 1), 0.5)


if __name__ == "__main__":
    unittest.main()
