#!/usr/bin/env python3
"""Gaussians close in front of each Panoptic camera: the near-plane finding of BENCHMARKS.md.

    atex convert MODEL.atex model_t0.ply --time 0
    python3 bench/near_camera_opacity.py model_t0.ply DATASET_DIR [--depth 0.2]

For every camera of the dataset's train_meta.json and test_meta.json (timestep 0), prints how
many Gaussians project into its image at a depth in (--near, --depth] scene units (drawn with a
0.01 near plane, culled by 0.2) and the sum of their opacities.
A held-out camera that sees opaque Gaussians this close has a blob over its image unless the
renderer culls them (the 0.2 near plane). Needs numpy.
"""

import argparse
import json
import os

import numpy as np


def read_ply(path):
    """Binary little-endian 3DGS PLY of float32 properties: {name: array}."""
    with open(path, "rb") as f:
        names, count = [], 0
        while True:
            line = f.readline()
            if not line:
                raise ValueError("%s: no end_header" % path)
            words = line.split()
            if words[:2] == [b"element", b"vertex"]:
                count = int(words[2])
            elif words[:1] == [b"property"]:
                if words[1] != b"float":
                    raise ValueError("%s: property %s is not float32" % (path, words[-1].decode()))
                names.append(words[-1].decode())
            elif words[:1] == [b"end_header"]:
                break
        data = np.frombuffer(f.read(4 * len(names) * count), dtype="<f4").reshape(count, len(names))
    return {n: data[:, i] for i, n in enumerate(names)}


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("ply")
    p.add_argument("dataset")
    p.add_argument("--depth", type=float, default=0.2, help="farthest depth counted (the new near plane)")
    p.add_argument("--near", type=float, default=0.01, help="nearest depth counted (the old near plane)")
    a = p.parse_args()
    g = read_ply(a.ply)
    xyz = np.stack([g["x"], g["y"], g["z"]], 1).astype(np.float64)
    opacity = 1.0 / (1.0 + np.exp(-g["opacity"].astype(np.float64)))
    for split in ("test", "train"):
        meta = json.load(open(os.path.join(a.dataset, "%s_meta.json" % split)))
        for i, cam in enumerate(meta["cam_id"][0]):
            w2c = np.array(meta["w2c"][0][i])
            k = np.array(meta["k"][0][i])
            pc = xyz @ w2c[:3, :3].T + w2c[:3, 3]
            z = pc[:, 2]
            with np.errstate(divide="ignore", invalid="ignore"):
                u = k[0, 0] * pc[:, 0] / z + k[0, 2]
                v = k[1, 1] * pc[:, 1] / z + k[1, 2]
            # Between the two near planes (drawn with the old one, culled by the new one), centre in the image.
            near = (z > a.near) & (z <= a.depth) & (u >= 0) & (u < meta["w"]) & (v >= 0) & (v < meta["h"])
            print("%-5s camera %2d: %4d Gaussians at depth (%.2f, %.2f], summed opacity %.2f"
                  % (split, cam, int(near.sum()), a.near, a.depth, float(opacity[near].sum())))


if __name__ == "__main__":
    main()
