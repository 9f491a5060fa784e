#!/usr/bin/env python3
"""Python overhead on a render: atex.render from Python against `atex fps` (issue 22: <= 5 %).

Python: atex.render(asset, camera, backend=...) in a loop (the asset is loaded into the backend
once, by the first call), wall clock per call, median of --repeats after 10 warm-up renders;
once returning a numpy array and once an atex.Tensor. C++: `atex fps --json` on the same asset,
dataset view and size (on CUDA: CUDA events around renders whose image stays on the device; on
the CPU: wall clock around Backend::Render). The camera is re-framed to --size exactly as
`atex fps --size` does.

  PYTHONPATH=BUILD/python python3 bench/python_overhead.py --atex BUILD/bin/atex --asset MODEL.atex \
      --data DATASET [--view test:0] [--size 1352x1014] [--backend cuda] [--repeats 200]
Prints one JSON object.
"""

import argparse
import json
import statistics
import subprocess
import time


def reframe(camera, width, height):
    import atex
    s = width / camera.width
    return atex.Camera(width, height, camera.fx * s, camera.fy * s, camera.cx * s + 0.5 * (width - camera.width * s),
                       camera.cy * s + 0.5 * (height - camera.height * s), camera.world_to_camera, camera.time,
                       camera.name)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--atex", required=True)
    p.add_argument("--asset", required=True)
    p.add_argument("--data", required=True)
    p.add_argument("--view", default="test:0")
    p.add_argument("--size", default="1352x1014")
    p.add_argument("--backend", default="cuda")
    p.add_argument("--repeats", type=int, default=200)
    a = p.parse_args()

    import atex
    fps = json.loads(subprocess.run([a.atex, "fps", a.asset, "--data", a.data, "--view", a.view, "--size", a.size,
                                     "--backend", a.backend, "--repeats", str(a.repeats), "--json"],
                                    capture_output=True, text=True, check=True).stdout)
    split, index = a.view.split(":")
    dataset = atex.Dataset(a.data)
    view = (dataset.test_views if split == "test" else dataset.train_views)[int(index)]
    width, height = (int(v) for v in a.size.split("x"))
    camera = reframe(view.camera, width, height)
    asset = atex.read(a.asset)
    result = {"asset": a.asset, "size": a.size, "backend": a.backend, "gaussians": asset.gaussian_count,
              "cli_median_ms": fps["median_ms"], "cli_method": fps["method"], "cli_backend": fps["backend"]}
    for output in ("tensor", "numpy"):
        for _ in range(10):
            atex.render(asset, camera, backend=a.backend, output=output)
        times = []
        for _ in range(a.repeats):
            start = time.perf_counter()
            atex.render(asset, camera, backend=a.backend, output=output)
            times.append((time.perf_counter() - start) * 1e3)
        median = statistics.median(times)
        result[f"python_{output}_median_ms"] = round(median, 4)
        result[f"python_{output}_overhead"] = round(median / fps["median_ms"] - 1, 4)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
