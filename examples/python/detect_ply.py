#!/usr/bin/env python3
"""Read a PLY with Open3D, detect furniture in it, save a picture of the cloud with its boxes.

    python3 examples/python/detect_ply.py [SCAN.ply] [--graph configs/scannet.json] [--out DIR]

Writes DIR/detections.png (a top view: the points in their colours, each detection's box and
class; accepted boxes solid, rejected ones dashed) and DIR/boxes.ply (the boxes as an Open3D
LineSet, to open over the scan in Open3D, MeshLab or CloudCompare). The default scan is a ScanNet
dev room of ../shared/data (a room reconstruction: configs/scannet.json's route).
"""
import argparse
import os
import pathlib

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt
import numpy as np
import open3d as o3d

import furnihost

ROOT = pathlib.Path(__file__).resolve().parents[2]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scan", nargs="?", default=ROOT.parent / "shared/data/scannet_votenet50k/scene0001_00.ply")
    ap.add_argument("--graph", default=ROOT / "configs" / "scannet.json")
    ap.add_argument("--out", default="furnihost-out/python_detect")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)

    cloud = o3d.io.read_point_cloud(str(args.scan))
    if cloud.is_empty():
        raise SystemExit(f"{args.scan}: Open3D read no points")
    graph = furnihost.Graph(args.graph)
    detections = graph.detect(cloud)  # an Open3D cloud as it is; numpy (N, 3) arrays work the same
    for d in detections:
        print(d)

    points = np.asarray(cloud.points)
    colors = np.asarray(cloud.colors) if cloud.has_colors() else None
    fig, ax = plt.subplots(figsize=(8, 8))
    order = np.argsort(points[:, 2])  # higher points drawn last: the top view
    ax.scatter(points[order, 0], points[order, 1], s=0.5, c=colors[order] if colors is not None else points[order, 2],
               cmap=None if colors is not None else "viridis", linewidths=0)
    for d in detections:
        if d.size is None:
            continue
        corners = np.asarray(d.to_dict()["box"]["corners"])
        bottom = corners[np.argsort(corners[:, 2])[:4], :2]
        centre = bottom.mean(axis=0)
        ring = bottom[np.argsort(np.arctan2(bottom[:, 1] - centre[1], bottom[:, 0] - centre[0]))]
        ring = np.vstack([ring, ring[:1]])
        colour = furnihost.class_color(d.class_name)
        ax.plot(ring[:, 0], ring[:, 1], color=colour, lw=2 if d.accepted else 1, ls="-" if d.accepted else "--")
        if d.accepted:
            ax.text(centre[0], centre[1], f"{d.class_name}\n{d.score:.2f}", color=colour, ha="center", va="center",
                    fontsize=8, weight="bold")
    accepted = sum(d.accepted for d in detections)
    ax.set_title(f"{pathlib.Path(args.scan).name}: {accepted} accepted of {len(detections)} detections")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    picture = os.path.join(args.out, "detections.png")
    fig.savefig(picture, dpi=120, bbox_inches="tight")
    boxes = os.path.join(args.out, "boxes.ply")
    o3d.io.write_line_set(boxes, furnihost.boxes_lineset([d for d in detections if d.accepted]))
    print(f"-> {picture}, {boxes}")
    if accepted == 0:
        raise SystemExit("no detection accepted")


if __name__ == "__main__":
    main()
