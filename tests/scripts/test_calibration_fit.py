#!/usr/bin/env python3
"""scripts/calibration_fit.py on hand-worked cases (stdlib unittest): the logistic map the
calibration files hold, the reliability bins and ECE, the working point, the part_of rule."""
import importlib.util
import math
import os
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
spec = importlib.util.spec_from_file_location("calibration_fit", os.path.join(ROOT, "scripts", "calibration_fit.py"))
cf = importlib.util.module_from_spec(spec)
spec.loader.exec_module(cf)


class Features(unittest.TestCase):
    def test_names(self):
        self.assertAlmostEqual(cf.feature_value("log_score", 0.2, {}), math.log(0.2))
        self.assertAlmostEqual(cf.feature_value("log_score", 0.0, {}), math.log(1e-6))  # floored
        self.assertEqual(cf.feature_value("evidence:points", 1.0, {"points": 400}), 400.0)
        self.assertAlmostEqual(cf.feature_value("log_evidence:points", 1.0, {"points": 400}), math.log(400))
        self.assertEqual(cf.feature_value("evidence:missing", 1.0, {}), 0.0)
        with self.assertRaises(ValueError):
            cf.feature_value("size", 1.0, {})


class Logistic(unittest.TestCase):
    def test_recovers_a_known_map_in_raw_units(self):
        # Labels drawn exactly at the map's rates: 1000 detections at each of five scores, the share
        # sigmoid(2 + 1.5 ln s) of them true. The fit (a faint penalty) gives back the map.
        x, y = [], []
        for s in (0.02, 0.05, 0.1, 0.2, 0.4):
            p = cf.sigmoid(2.0 + 1.5 * math.log(s))
            n_true = round(1000 * p)
            x += [[math.log(s)]] * 1000
            y += [1] * n_true + [0] * (1000 - n_true)
        coef, b = cf.fit_logistic(x, y, l2=1e-6)
        self.assertAlmostEqual(coef[0], 1.5, delta=0.02)
        self.assertAlmostEqual(b, 2.0, delta=0.05)
        self.assertAlmostEqual(cf.confidence(coef, b, [math.log(0.1)]), cf.sigmoid(2.0 + 1.5 * math.log(0.1)), delta=0.005)

    def test_a_class_without_a_true_positive_gets_a_finite_low_map(self):
        coef, b = cf.fit_logistic([[0.0], [1.0], [2.0]], [0, 0, 0])
        self.assertTrue(all(math.isfinite(v) for v in coef + [b]))
        self.assertLess(cf.confidence(coef, b, [1.0]), 0.01)


class Reliability(unittest.TestCase):
    def test_bins_and_ece_by_hand(self):
        # Bin 0.1-0.2: mean 0.15, half true (0.35 off); bin 0.9-1.0: mean 0.975, all true (0.025 off).
        ece, bins = cf.reliability([(0.15, True), (0.15, False), (0.95, True), (1.0, True)])
        self.assertAlmostEqual(ece, (2 * 0.35 + 2 * 0.025) / 4)
        self.assertEqual(bins[1][2], 2)
        self.assertAlmostEqual(bins[1][4], 0.5)
        self.assertEqual(bins[9][2], 2)
        self.assertEqual(bins[5][2], 0)
        self.assertTrue(math.isnan(cf.reliability([])[0]))

    def test_working_point(self):
        tp, fp, p, r = cf.working_point([(0.9, True), (0.6, False), (0.5, True), (0.4, True)], 5)
        self.assertEqual((tp, fp), (2, 1))
        self.assertAlmostEqual(p, 2 / 3)
        self.assertAlmostEqual(r, 2 / 5)


class PartOf(unittest.TestCase):
    # The cases of the host's test (tests/unit/test_calibration.cpp,
    # Calibration.PartOfDropsASeatReadAsAChairInsideAMoreProbableSofa): the two rules agree.
    def dets(self, sofa7_accepted):
        # Accepted here: confidence >= 0.5 (the C++ test's sofa 7 is not accepted at 0.9 by its
        # verdict; here it is below 0.5 instead).
        rows = [("sofa", (0, 0, 0), (1.6, 0.9, 0.8), 0.9), ("chair", (0.1, 0, 0), (0.9, 0.8, 0.8), 0.45),
                ("table", (0.2, 0.1, 0), (0.8, 0.6, 0.4), 0.3), ("chair", (2.0, 0, 0), (2.8, 0.8, 0.8), 0.7),
                ("sofa", (5, 0, 0), (6.7, 0.9, 0.8), 0.6), ("chair", (5, 0, 0), (5.8, 0.85, 0.8), 0.5),
                ("chair", (5.9, 0, 0), (6.7, 0.85, 0.8), 0.45),
                ("sofa", (9, 0, 0), (10.6, 0.9, 0.8), 0.9 if sofa7_accepted else 0.45),
                ("chair", (9.1, 0, 0), (9.9, 0.8, 0.8), 0.2), ("chair", (10.4, 0, 0), (11.2, 0.8, 0.8), 0.1)]
        return [{"cls": c, "box": (lo, hi), "confidence": p} for c, lo, hi, p in rows]

    def test_a_seat_inside_a_more_probable_sofa_is_dropped(self):
        self.assertEqual(cf.part_of_pairs(" chair : sofa, "), [("chair", "sofa")])
        self.assertEqual(cf.part_of_pairs(""), [])
        pairs = cf.part_of_pairs("chair:sofa")
        dets = self.dets(False)
        kept = cf.drop_parts(dets, pairs, 0.5, 0.5)
        self.assertEqual([dets.index(d) for d in kept], [0, 2, 3, 4, 5, 6, 7, 8, 9])
        dets = self.dets(True)
        kept = cf.drop_parts(dets, pairs, 0.5, 0.5)
        self.assertEqual([dets.index(d) for d in kept], [0, 2, 3, 4, 5, 6, 7, 9])
        self.assertEqual(cf.drop_parts(dets, [], 0.5, 0.5), dets)


if __name__ == "__main__":
    unittest.main()
