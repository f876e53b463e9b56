#!/usr/bin/env python3
"""Single depth-camera views cut from the real ScanNet rooms: a dev set of real single views WITH
chairs, tables and sofas (sunrgbd_dev.json has bedrooms only).

Each room of benchmarks/scannet_dev.json is seen by up to four virtual cameras standing in it, one
looking along each of the room's axes (+x, -x, +y, -y), 1.3 m above the floor, pitched 15 deg down,
320 x 240 px with a 262.5 px focal length (a Kinect's field of view, as scripts/make_synthetic_views.sh).
Each camera stands where, on a 0.3 m grid of open floor (nothing within ~0.3 m between 0.2 and 2 m
up), its frustum holds the most points of the evaluated objects 0.8-5 m away, as a photographer
frames the furniture; a view seeing fewer than 2000 points is left out.
What a camera sees is decided by a z-buffer of the room's points drawn as discs (radius 2x the
room's median point spacing, so the sampled surfaces are closed), at most 6 m away. The points seen
are written in the camera's upright frame as SUN RGB-D gives its views (camera at the origin, z up,
y forward, x right, the floor about 1.3 m below), with the ground truth boxes moved into it; a
ground-truth object is kept when at least 30 % of its points (and 50 points) are seen: half-seen
objects are annotated in SUN RGB-D too. Headings along the room's axes keep the axis-aligned boxes
axis-aligned.

Real reconstructed geometry (holes, missing undersides, clutter) in a single view, but the room's
density (1.4-3.3 cm) and a reconstruction's noise, not a depth camera's range noise: a proxy for
real single views of offices and living rooms, not a substitute. ScanNet's terms forbid copying its
data, so the views are made on the machine (seconds) into --out and never committed.

usage: scripts/make_scannet_views.py [--dataset benchmarks/scannet_dev.json] [--out runs/scannet_views]
then:  furnihost eval --graph configs/rgbd_view.json --dataset runs/scannet_views/dataset.json
"""
import argparse
import json
import math
import os
import struct
import sys

W, H, F = 320, 240, 262.5
CX, CY = (W - 1) / 2.0, (H - 1) / 2.0
HEIGHT, PITCH_DEG, MAX_RANGE = 1.3, 15.0, 6.0
MIN_FRACTION, MIN_POINTS, MIN_VIEW_POINTS = 0.3, 50, 2000


class InputError(Exception):
    """A bad input file: one line naming it, exit 2."""


def load_json(path):
    with open(path) as f:
        try:
            return json.load(f)
        except json.JSONDecodeError as e:
            raise InputError(f"{path}: not valid JSON: {e}") from None


def read_ply(path):
    with open(path, "rb") as f:
        data = f.read()
    if b"end_header\n" not in data[:65536]:
        raise InputError(f"{path}: not a PLY file (no end_header line)")
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii", "replace").splitlines()
    if "format binary_little_endian 1.0" not in header:
        raise InputError(f"{path}: expected a binary little-endian PLY")
    n, props = 0, []
    kinds = {"float": "f", "uchar": "B", "ushort": "H", "int": "i", "uint": "I", "double": "d", "short": "h", "char": "b"}
    for line in header:
        t = line.split()
        if t[:2] == ["element", "vertex"]:
            n = int(t[2])
        elif t[:1] == ["property"] and len(t) == 3:
            if t[1] not in kinds:
                raise InputError(f"{path}: vertex property {t[2]} has an unknown type {t[1]}")
            props.append((t[2], kinds[t[1]]))
    fmt = "<" + "".join(k for _, k in props)
    size = struct.calcsize(fmt)
    names = [p for p, _ in props]
    if len(data) < end + n * size:
        raise InputError(f"{path}: {n} vertices of {size} bytes announced, the file is shorter")
    rows = [struct.unpack_from(fmt, data, end + i * size) for i in range(n)]
    col = {name: [r[j] for r in rows] for j, name in enumerate(names)}
    for need in ("x", "y", "z", "red", "green", "blue"):
        if need not in col:
            raise InputError(f"{path}: no vertex property {need}")
    return col, n


def write_ply(path, pts, rgb):
    with open(path + ".tmp", "wb") as f:
        f.write(("ply\nformat binary_little_endian 1.0\ncomment single view cut from a ScanNet room by "
                 "scripts/make_scannet_views.py (camera at the origin, z up, y forward)\n"
                 f"element vertex {len(pts)}\nproperty float x\nproperty float y\nproperty float z\n"
                 "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n").encode())
        for p, c in zip(pts, rgb):
            f.write(struct.pack("<fffBBB", p[0], p[1], p[2], c[0], c[1], c[2]))
    os.replace(path + ".tmp", path)


def percentile(v, q):
    s = sorted(v)
    return s[min(len(s) - 1, max(0, int(q * (len(s) - 1) + 0.5)))]


def median_spacing(xs, ys, zs, cell=0.1, sample=4000):
    """Median nearest-neighbour distance of a stride sample of the points (a grid of 10 cm cells)."""
    grid = {}
    n = len(xs)
    for i in range(n):
        grid.setdefault((int(math.floor(xs[i] / cell)), int(math.floor(ys[i] / cell)), int(math.floor(zs[i] / cell))), []).append(i)
    d = []
    for i in range(0, n, max(1, n // sample)):
        k = (int(math.floor(xs[i] / cell)), int(math.floor(ys[i] / cell)), int(math.floor(zs[i] / cell)))
        best = cell
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for dz in (-1, 0, 1):
                    for j in grid.get((k[0] + dx, k[1] + dy, k[2] + dz), ()):
                        if j != i:
                            e = math.sqrt((xs[i] - xs[j]) ** 2 + (ys[i] - ys[j]) ** 2 + (zs[i] - zs[j]) ** 2)
                            if 0 < e < best:
                                best = e
        d.append(best)
    return percentile(d, 0.5)


def view(col, n, cam, heading, splat):
    """Indices of the points a camera at cam looking along heading (unit xy) sees, and each one's
    upright-frame coordinates (x right, y forward, z up, camera at the origin)."""
    fx, fy = heading
    rx, ry = fy, -fx  # right = forward x up
    cp, sp = math.cos(math.radians(PITCH_DEG)), math.sin(math.radians(PITCH_DEG))
    xs, ys, zs = col["x"], col["y"], col["z"]
    up_pts, cam_pts = [None] * n, [None] * n
    zbuf = [math.inf] * (W * H)
    for i in range(n):
        dx, dy, dz = xs[i] - cam[0], ys[i] - cam[1], zs[i] - cam[2]
        X, Y, Z = dx * rx + dy * ry, dx * fx + dy * fy, dz
        up_pts[i] = (X, Y, Z)
        # optical frame of the pitched camera: x right, y down, z forward
        zc = Y * cp - Z * sp
        yc = -(Z * cp + Y * sp)
        if zc < 0.3 or math.sqrt(X * X + Y * Y + Z * Z) > MAX_RANGE:
            continue
        u, v = CX + F * X / zc, CY + F * yc / zc
        r = F * splat / zc
        if u < -r or u > W - 1 + r or v < -r or v > H - 1 + r:
            continue
        cam_pts[i] = (u, v, zc)
        u0, u1 = max(0, int(math.floor(u - r))), min(W - 1, int(math.ceil(u + r)))
        v0, v1 = max(0, int(math.floor(v - r))), min(H - 1, int(math.ceil(v + r)))
        r2 = r * r
        for py in range(v0, v1 + 1):
            ddy = (py - v) ** 2
            if ddy > r2:
                continue
            row = py * W
            for px in range(u0, u1 + 1):
                if (px - u) ** 2 + ddy <= r2 and zc < zbuf[row + px]:
                    zbuf[row + px] = zc
    seen = []
    for i in range(n):
        c = cam_pts[i]
        if c is None:
            continue
        u, v, zc = c
        pu, pv = int(round(u)), int(round(v))
        if not (0 <= pu < W and 0 <= pv < H):
            continue
        if zc <= zbuf[pv * W + pu] + 0.03 + 0.02 * zc:
            seen.append(i)
    return seen, up_pts


def box_in_view(centre, size, cam, heading):
    """An axis-aligned box (centre, [dx, dy, dz]) of the room in the upright frame of a camera at cam
    looking along heading (one of the room's axes): the centre moved, x and y extents swapped when
    the camera looks along x."""
    fx, fy = heading
    rx, ry = fy, -fx
    dx, dy, dz = centre[0] - cam[0], centre[1] - cam[1], centre[2] - cam[2]
    sx, sy, sz = size
    return [dx * rx + dy * ry, dx * fx + dy * fy, dz], ([sy, sx, sz] if fx != 0 else [sx, sy, sz])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dataset", default="benchmarks/scannet_dev.json")
    ap.add_argument("--out", default="runs/scannet_views")
    args = ap.parse_args()
    base = os.path.dirname(os.path.abspath(args.dataset))
    manifest = load_json(args.dataset)
    os.makedirs(args.out, exist_ok=True)
    scenes = []
    for sc in manifest["scenes"]:
        scan = os.path.join(base, sc["scan"])
        gt = load_json(os.path.join(base, sc["gt"]))
        col, n = read_ply(scan)
        if "instance" not in col:
            raise InputError(f"{scan}: no per-point 'instance' property (needed to count each object's "
                             "points seen)")
        xs, ys, zs = col["x"], col["y"], col["z"]
        floor = percentile(zs, 0.01)
        spacing = median_spacing(xs, ys, zs)
        lo = (percentile(xs, 0.02), percentile(ys, 0.02))
        hi = (percentile(xs, 0.98), percentile(ys, 0.98))
        centre = ((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2)
        stem = os.path.splitext(os.path.basename(scan))[0]
        per_instance = {}
        for i in range(n):
            per_instance[col["instance"][i]] = per_instance.get(col["instance"][i], 0) + 1
        evaluated = set(manifest["classes"]) | {k for k, v in manifest.get("class_map", {}).items() if v}
        wanted = {o.get("instance_id") for o in gt["objects"] if o["class"] in evaluated}
        obj_pts = [i for i in range(0, n, 2) if col["instance"][i] in wanted]
        # Standpoints: a 0.3 m grid over the room, at least 0.5 m from any point between 0.2 and
        # 2.0 m above the floor, with floor under it (inside the room).
        occupied, floor_cells = set(), set()
        for i in range(0, n, 2):
            cell = (int(math.floor(xs[i] / 0.25)), int(math.floor(ys[i] / 0.25)))
            if floor + 0.2 < zs[i] < floor + 2.0:
                occupied.add(cell)
            elif zs[i] < floor + 0.1:
                floor_cells.add(cell)
        stands = []
        gx = lo[0]
        while gx <= hi[0]:
            gy = lo[1]
            while gy <= hi[1]:
                cx, cy = int(math.floor(gx / 0.25)), int(math.floor(gy / 0.25))
                free = all((cx + a, cy + b) not in occupied for a in (-1, 0, 1) for b in (-1, 0, 1))
                if free and (cx, cy) in floor_cells:
                    stands.append((gx, gy))
                gy += 0.3
            gx += 0.3
        tx, ty = math.tan(math.atan(CX / F)), CY / F
        cp, sp = math.cos(math.radians(PITCH_DEG)), math.sin(math.radians(PITCH_DEG))
        for name, h in (("px", (1.0, 0.0)), ("nx", (-1.0, 0.0)), ("py", (0.0, 1.0)), ("ny", (0.0, -1.0))):
            axis = 0 if h[0] != 0 else 1
            # The standpoint whose frustum holds the most points of the evaluated objects 0.8-5 m
            # away (a photographer framing the furniture; occlusion decided afterwards).
            best, cam = 0, None
            for (sx_, sy_) in stands:
                c = (sx_, sy_, floor + HEIGHT)
                k = 0
                for i in obj_pts:
                    dx, dy, dz = xs[i] - c[0], ys[i] - c[1], zs[i] - c[2]
                    Y = dx * h[0] + dy * h[1]
                    if Y < 0.8:
                        continue
                    X = dx * h[1] - dy * h[0]
                    zc = Y * cp - dz * sp
                    yc = -(dz * cp + Y * sp)
                    if zc > 0.3 and abs(X) <= tx * zc and abs(yc) <= ty * zc and X * X + Y * Y < 25.0:
                        k += 1
                if k > best:
                    best, cam = k, list(c)
            if cam is None:
                print(f"  {stem} {name}: no standpoint sees an object, skipped", file=sys.stderr)
                continue
            seen, up = view(col, n, cam, h, 2.0 * spacing)
            if len(seen) < MIN_VIEW_POINTS:
                print(f"  {stem} {name}: {len(seen)} points seen, skipped", file=sys.stderr)
                continue
            seen_of = {}
            for i in seen:
                seen_of[col["instance"][i]] = seen_of.get(col["instance"][i], 0) + 1
            objects = []
            for o in gt["objects"]:
                k = seen_of.get(o.get("instance_id"), 0)
                total = per_instance.get(o.get("instance_id"), 0)
                if k < MIN_POINTS or k < MIN_FRACTION * total:
                    continue
                centre_v, size_v = box_in_view(o["center"], o["size"], cam, h)
                objects.append({"class": o["class"], "center": centre_v, "size": size_v,
                                "n_points": k, "of_points": total, "instance_id": o.get("instance_id")})
            vname = f"{stem}_{name}"
            write_ply(os.path.join(args.out, vname + ".ply"), [up[i] for i in seen],
                      [(col["red"][i], col["green"][i], col["blue"][i]) for i in seen])
            g = {"units": "m", "up": "z", "scene": vname, "sensor_origin": [0, 0, 0],
                 "frame": f"upright camera frame (camera at the origin, z up, y forward) of a virtual depth camera in "
                          f"{stem} at ({cam[0]:.3f}, {cam[1]:.3f}, {cam[2]:.3f}) looking along {name[1]} "
                          f"({'+' if name[0] == 'p' else '-'}), pitched {PITCH_DEG:g} deg down",
                 "floor_z": floor - cam[2], "objects": objects}
            with open(os.path.join(args.out, vname + ".gt.json"), "w") as f:
                json.dump(g, f, indent=1)
            scenes.append({"scan": vname + ".ply", "gt": vname + ".gt.json", "origin": [0, 0, 0]})
            counts = {}
            for o in objects:
                counts[o["class"]] = counts.get(o["class"], 0) + 1
            print(f"  {vname}: {len(seen)} points, {counts}", file=sys.stderr)
    out = {"description": "single views cut from the ScanNet dev rooms by scripts/make_scannet_views.py (camera at the "
                          "origin, z up, y forward, floor 1.3 m below): real reconstructed geometry in single views",
           "scenes": scenes, "class_map": manifest.get("class_map", {}), "classes": manifest["classes"]}
    with open(os.path.join(args.out, "dataset.json"), "w") as f:
        json.dump(out, f, indent=1)
    print(f"{len(scenes)} views -> {os.path.join(args.out, 'dataset.json')}", file=sys.stderr)


def fail(message):
    print(f"make_scannet_views: {message}", file=sys.stderr)
    sys.exit(2)


if __name__ == "__main__":
    try:
        main()
    except InputError as e:
        fail(str(e))
    except OSError as e:
        fail(f"{e.filename}: {e.strerror}" if e.filename else str(e))
    except json.JSONDecodeError as e:
        fail(f"not valid JSON: {e}")
    except (ValueError, KeyError, IndexError, TypeError, struct.error) as e:
        fail(f"{type(e).__name__}: {e}")
