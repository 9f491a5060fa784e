#!/usr/bin/env python3
"""How many training cameras see the space in front of each test camera (BENCHMARKS.md, stage 1,
"Observer-count pruning"), and optionally how many see each point of a PLY (e.g. an initial model
from `atex train --stage 1 --set stage1.coarse_iterations=0 --set stage1.fine_iterations=0`, then
`atex convert MODEL.atex OUT.ply`).

A training camera sees a point when the point lies beyond the near plane (camera z > 0.2, the
trainer's default) and projects inside its image: the rule of CountObservingCameras (densify.h).

  python3 bench/observer_coverage.py ../shared/data/panoptic_basketball [--ply POINTS.ply]
"""
import argparse
import json
import os

import numpy as np


def cameras(meta):
    """{camera id: (K 3x3, world-to-camera 4x4)} of the first timestep."""
    return {c: (np.array(k), np.array(w)) for c, k, w in zip(meta["cam_id"][0], meta["k"][0], meta["w2c"][0])}


def observers(points, train, width, height, near):
    count = np.zeros(len(points), dtype=int)
    for k, w in train.values():
        pc = points @ w[:3, :3].T + w[:3, 3]
        z = pc[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = (k[0, 0] * pc[:, 0] + k[0, 2] * z) / z
            v = (k[1, 1] * pc[:, 1] + k[1, 2] * z) / z
        count += (z > near) & (u >= 0) & (u < width) & (v >= 0) & (v < height)
    return count


def read_ply_positions(path):
    with open(path, "rb") as f:
        header = []
        while True:
            line = f.readline().decode().strip()
            header.append(line)
            if line == "end_header":
                break
        n = int(next(l for l in header if l.startswith("element vertex")).split()[-1])
        props = [l.split()[-1] for l in header if l.startswith("property")]
        data = np.frombuffer(f.read(n * 4 * len(props)), dtype="<f4").reshape(n, len(props))
    return data[:, [props.index("x"), props.index("y"), props.index("z")]].astype(np.float64)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("data", help="Panoptic folder with train_meta.json and test_meta.json")
    p.add_argument("--ply", help="also count the observers of every point of this PLY")
    p.add_argument("--near", type=float, default=0.2)
    a = p.parse_args()
    with open(os.path.join(a.data, "train_meta.json")) as f:
        train_meta = json.load(f)
    with open(os.path.join(a.data, "test_meta.json")) as f:
        test_meta = json.load(f)
    width, height = train_meta["w"], train_meta["h"]
    train = cameras(train_meta)
    pixels = [(width / 2, height / 2), (0.1 * width, 0.1 * height), (0.9 * width, 0.1 * height),
              (0.1 * width, 0.9 * height), (0.9 * width, 0.9 * height)]
    print("training cameras seeing points in front of each test camera (image centre, then the four corners at 10 %)")
    for cam, (k, w) in cameras(test_meta).items():
        rotation, centre = w[:3, :3], -w[:3, :3].T @ w[:3, 3]
        rows = []
        for depth in (0.3, 0.6, 1.0, 1.5, 2.0, 3.0):
            rays = [rotation.T @ np.linalg.solve(k, np.array([u, v, 1.0])) for u, v in pixels]
            points = np.array([centre + r * depth for r in rays])  # camera z = depth
            rows.append("%.1f m: %s" % (depth, observers(points, train, width, height, a.near).tolist()))
        print("camera %d: " % cam + "; ".join(rows))
    if a.ply:
        count = observers(read_ply_positions(a.ply), train, width, height, a.near)
        print("%s: %d points; fraction seen by fewer than K cameras: %s" % (
            a.ply, len(count), ", ".join("K=%d %.3f" % (k, (count < k).mean()) for k in (2, 3, 4, 5, 6, 8))))


if __name__ == "__main__":
    main()
