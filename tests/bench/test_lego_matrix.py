#!/usr/bin/env python3
"""End to end: bench/run_matrix.py with the REAL atex binary (CPU backend) on the tiny lego
(bench/configs/lego_cpu.json: 3 methods x {full, keep-count 50 %}, about 15 s), then bench/paired_bootstrap.py on its rows.

    python3 tests/bench/test_lego_matrix.py --atex build/bin/atex --out DIR
Data: $ATEX_DATA_DIR, else $ATEX_DATA_DIR_DEFAULT (../shared/data). Missing data: exit 77
(skip), or failure when ATEX_REQUIRE_DATA=1 (CI).
"""
import argparse
import json
import os
import shutil
import subprocess
import sys

SOURCE = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--atex", required=True)
    p.add_argument("--out", required=True)
    args = p.parse_args()
    data = os.environ.get("ATEX_DATA_DIR") or os.environ.get("ATEX_DATA_DIR_DEFAULT") or \
        os.path.join(SOURCE, "..", "shared", "data")
    lego = os.path.join(data, "dnerf_lego_tiny", "tiny_dnerf_data.npz")
    if not os.path.exists(lego):
        if os.environ.get("ATEX_REQUIRE_DATA") == "1":
            print("FAIL: real test data missing: %s" % lego)
            return 1
        print("SKIP: real test data missing (set ATEX_DATA_DIR): %s" % lego)
        return 77
    shutil.rmtree(args.out, ignore_errors=True)  # a fresh matrix (a resumed one would skip every cell)
    env = dict(os.environ, ATEX_DATA_DIR=os.path.abspath(data))
    cmd = [sys.executable, os.path.join(SOURCE, "bench", "run_matrix.py"),
           os.path.join(SOURCE, "bench", "configs", "lego_cpu.json"), "--atex", args.atex, "--out", args.out]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    print(proc.stdout + proc.stderr)
    if proc.returncode != 0:
        print("FAIL: run_matrix exited with %d" % proc.returncode)
        return 1
    rows = [json.loads(l) for l in open(os.path.join(args.out, "results.jsonl"))]
    bad = [r for r in rows if r["status"] != "ok"]
    if len(rows) != 6 or bad:
        print("FAIL: expected 6 ok rows, got %d (%s)" % (len(rows), [(r["cell"], r.get("cause")) for r in bad]))
        return 1
    by = {(r["method"], r["budget"]): r for r in rows}
    for m in ("none", "uniform", "adaptive"):
        if by[(m, "k50")]["gaussians"] * 2 > by[(m, "full")]["gaussians"] + 1:
            print("FAIL: %s k50 kept %s of %s Gaussians" % (m, by[(m, "k50")]["gaussians"],
                                                          by[(m, "full")]["gaussians"]))
            return 1
    for r in rows:
        textured = r["method"] != "none"
        if (r.get("texels") is not None) != textured or not r.get("views") or not r.get("fps_native"):
            print("FAIL: incomplete row %s" % json.dumps(r)[:500])
            return 1
    proc = subprocess.run([sys.executable, os.path.join(SOURCE, "bench", "paired_bootstrap.py"),
                           os.path.join(args.out, "results.jsonl"), "--baseline", "none", "--samples", "500"],
                          capture_output=True, text=True)
    print(proc.stdout + proc.stderr)
    if proc.returncode != 0 or "uniform - none" not in proc.stdout:
        print("FAIL: paired_bootstrap")
        return 1
    print("ok: 6 cells, paired bootstrap over %d views" % len(rows[0]["views"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
