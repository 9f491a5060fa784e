#!/usr/bin/env python3
"""Reading an .atex into numpy from Python against the C++ read (issue 22's target: <= 1.2x).

Python: atex.read(path) and the numpy views of every array (Gaussians, texture pool, deformation
grids and weights), median of --repeats wall-clock runs after one warm-up. C++: bench_container's
ReadFile benchmark (atex::ReadAssetFile on the same file, Google Benchmark, real time).
Both read the file from the page cache (it is read once before timing).

  PYTHONPATH=build/python python3 bench/python_read.py --bench build/bench/bench_container \
      [--asset samples/lego_adaptive_2MiB.atex] [--repeats 30]
Prints one JSON object: medians python_ms, cpp_ms and their ratio; minima and their ratio_min.
"""

import argparse
import json
import os
import statistics
import subprocess
import time


def touch_every_array(asset):
    g = asset.gaussians
    arrays = [g.positions, g.rotations, g.log_scales, g.opacity_logits, g.sh]
    if asset.textures is not None:
        t = asset.textures
        arrays += [t.heights, t.widths, t.axis_u, t.axis_v, t.offsets, t.texels]
    if asset.deformation is not None:
        d = asset.deformation
        arrays += [p for scale in d.planes for p in scale] + [a for layer in d.trunk for a in layer]
        arrays += [a for head in d.heads if head for layer in head for a in layer]
    return sum(a.nbytes for a in arrays)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--bench", required=True, help="the bench_container executable")
    parser.add_argument("--asset", default="samples/lego_adaptive_2MiB.atex")
    parser.add_argument("--repeats", type=int, default=30)
    args = parser.parse_args()

    import atex
    with open(args.asset, "rb") as f:
        f.read()
    touch_every_array(atex.read(args.asset))  # warm-up
    times = []
    for _ in range(args.repeats):
        start = time.perf_counter()
        nbytes = touch_every_array(atex.read(args.asset))
        times.append((time.perf_counter() - start) * 1e3)
    python_ms = statistics.median(times)

    env = dict(os.environ, ATEX_BENCH_READ_FILE=os.path.abspath(args.asset))
    out = subprocess.run([args.bench, "--benchmark_filter=^ReadFile/", "--benchmark_format=json",
                          f"--benchmark_repetitions={max(3, args.repeats // 10)}"],
                         capture_output=True, text=True, check=True, env=env).stdout
    runs = [b for b in json.loads(out)["benchmarks"] if b.get("run_type") == "iteration"]
    cpp_ms = statistics.median(b["real_time"] for b in runs)  # Unit: milliseconds
    cpp_min_ms = min(b["real_time"] for b in runs)
    # Medians and minima: on a shared machine the minimum is the least disturbed run of each.
    print(json.dumps({"asset": args.asset, "array_bytes": nbytes, "python_ms": round(python_ms, 3),
                      "python_min_ms": round(min(times), 3), "cpp_ms": round(cpp_ms, 3),
                      "cpp_min_ms": round(cpp_min_ms, 3), "ratio": round(python_ms / cpp_ms, 3),
                      "ratio_min": round(min(times) / cpp_min_ms, 3), "repeats": args.repeats,
                      "cpp_repetitions": len(runs)}))


if __name__ == "__main__":
    main()
