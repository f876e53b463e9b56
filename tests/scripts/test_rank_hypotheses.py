#!/usr/bin/env python3
"""scripts/rank_hypotheses.py on hand-made hypotheses: the room frame of a view's box, the seat
beside a hypothesis, the oracle AP per kind of false positive (stdlib unittest)."""
import importlib.util
import math
import os
import sys
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "scripts"))
spec = importlib.util.spec_from_file_location("rank_hypotheses", os.path.join(ROOT, "scripts", "rank_hypotheses.py"))
rh = importlib.util.module_from_spec(spec)
spec.loader.exec_module(rh)
spec = importlib.util.spec_from_file_location("make_scannet_views", os.path.join(ROOT, "scripts", "make_scannet_views.py"))
mv = importlib.util.module_from_spec(spec)
spec.loader.exec_module(mv)


def chair_at(x, half=0.35, top=0.8):
    """A saved detection facing -y, its box 2 half wide and deep, standing on the ground at z 0."""
    c = [x, 0.0, top / 2]
    corners = [[x + sx * half, sy * half, z] for z in (0.0, top) for sx, sy in ((1, 1), (-1, 1), (-1, -1), (1, -1))]
    return {"facing": [0.0, -1.0, 0.0], "box": {"center": c, "corners": corners, "yaw": -math.pi / 2,
                                                  "bottom_above_ground": 0.0,
                                                  "aabb": {"min": [x - half, -half, 0.0], "max": [x + half, half, top]}}}


def slab(x0, x1, y0, y1, z, step=0.02):
    return [(x0 + i * step, y0 + j * step, z) for i in range(int((x1 - x0) / step) + 1)
            for j in range(int((y1 - y0) / step) + 1)]


class RoomBox(unittest.TestCase):
    def test_view_box_goes_back_where_make_scannet_views_took_it(self):
        # A room box moved into a view by make_scannet_views.box_in_view comes back to the room.
        for name, heading in (("px", (1, 0)), ("nx", (-1, 0)), ("py", (0, 1)), ("ny", (0, -1))):
            cam = (1.0, -2.0, 1.3)
            centre, size = (2.5, 0.5, 0.4), (0.6, 1.2, 0.8)
            vc, vs = mv.box_in_view(centre, size, cam, heading)
            vbox = (tuple(c - s / 2 for c, s in zip(vc, vs)), tuple(c + s / 2 for c, s in zip(vc, vs)))
            frame = (f"upright camera frame of a virtual depth camera in scene0001_00 at ({cam[0]:.3f}, {cam[1]:.3f}, "
                     f"{cam[2]:.3f}) looking along {name[1]} ({'+' if name[0] == 'p' else '-'}), pitched 15 deg down")
            room, rb = rh.room_box(frame, vbox)
            self.assertEqual(room, "scene0001_00")
            want = (tuple(c - s / 2 for c, s in zip(centre, size)), tuple(c + s / 2 for c, s in zip(centre, size)))
            for k in range(3):
                self.assertAlmostEqual(rb[0][k], want[0][k], places=6, msg=name)
                self.assertAlmostEqual(rb[1][k], want[1][k], places=6, msg=name)

    def test_a_frame_without_a_camera_gives_no_room(self):
        self.assertEqual(rh.room_box("camera at the origin", ((0, 0, 0), (1, 1, 1))), (None, None))


class SideSeat(unittest.TestCase):
    def test_a_seat_going_on_past_the_side_and_not_the_floor_beside_it(self):
        det = chair_at(0.0)
        chair = slab(-0.35, 0.35, -0.35, 0.35, 0.45) + slab(-0.35, 0.35, 0.3, 0.35, 0.8)
        floor = slab(-1.0, 1.0, -0.6, 0.6, 0.0)
        # An armchair on the floor: nothing at seat height beside it.
        self.assertLess(rh.side_seat(chair + floor, det), 0.05)
        # One end of a sofa: its seat goes on 0.8 m past the right side.
        sofa = chair + slab(0.35, 1.15, -0.35, 0.35, 0.45)
        self.assertGreater(rh.side_seat(sofa, det), 0.9)
        # A table top beside it is not a seat.
        table = chair + slab(0.4, 1.2, -0.35, 0.35, 0.75)
        self.assertLess(rh.side_seat(table, det), 0.05)


def row(score, tp, gt="none", room_gt=""):
    return {"score": score, "tp": tp, "gt": gt, "room_gt": room_gt}


class Oracle(unittest.TestCase):
    def test_each_kind_taken_out(self):
        rows = [row(0.9, False, "sofa"), row(0.8, True, "chair"), row(0.7, False, "none", "chair"),
                row(0.6, True, "chair"), row(0.5, False)]
        got = dict(rh.oracle(rows, 2))
        self.assertAlmostEqual(rh.ap25(rows, 2), 0.5 * 0.5 + 0.5 * 0.5)
        self.assertAlmostEqual(got["sofa"], 0.5 * 1 + 0.5 * 2 / 3)
        self.assertAlmostEqual(got["none/room chair"], 2 / 3)  # precision interpolated: 2/3 at both recalls
        self.assertAlmostEqual(got["none"], rh.ap25(rows, 2))  # the last false positive is below both
        self.assertAlmostEqual(got["all but none"], 1.0)


if __name__ == "__main__":
    unittest.main()
