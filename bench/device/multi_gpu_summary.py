#!/usr/bin/env python3
"""Summary of bench/device/multi_gpu_session.sh's rows (issue 25): scaling, the all-reduce's share
of a step, quality and wall time at the defaults (two seeds on 1 and 2 GPUs), resume across GPU
counts, and the memory phase. Usage: multi_gpu_summary.py DIR > DIR/summary.json
MGS_SEEDS (two seeds, the first the checkpointed one; default "6666 1") names the runs, as in
multi_gpu_session.sh."""
import json
import os
import statistics
import sys

d = sys.argv[1]
seeds = os.environ.get("MGS_SEEDS", "6666 1").split()
first = "s" + seeds[0]


def load(name):
    path = os.path.join(d, name)
    try:
        return json.load(open(path))
    except (OSError, ValueError):
        return None


summary = {"scale": load("scale/multi_gpu.json"), "memory": load("memory/memory.json")}

profile = {}
for gpus in (1, 2, 4):
    train = load(f"profile_{gpus}gpu.train.json")
    if not train or not train.get("profile"):
        continue
    p = train["profile"]
    steps = p.get("steps") or 1
    row = {"step_ms": p["total_ms"] / steps}
    if "all_reduce_ms" in p:
        row["all_reduce_ms"] = p["all_reduce_ms"] / steps
        row["all_reduce_share"] = p["all_reduce_ms"] / p["total_ms"]
    profile[f"{gpus}gpu"] = row
summary["profile_per_step"] = profile

runs = {}
names = [f"q{g}_s{seed}" for g in (1, 2) for seed in seeds] + ["resume_2to1", "resume_1to2"]
for name in names:
    train, ev = load(name + ".train.json"), load(name + ".eval.json")
    row = {}
    try:
        row["wall_s"] = float(open(os.path.join(d, name + ".wall")).read())
    except (OSError, ValueError):
        pass
    if train:
        row["seconds"] = train.get("seconds")
        row["steps"] = train.get("steps")
        row["gaussians"] = train.get("gaussians")
        row["peak_memory_bytes"] = train.get("peak_memory_bytes")
    if ev:
        row["test_psnr"] = ev.get("mean", {}).get("psnr")
    runs[name] = row
summary["runs"] = runs


def psnr(name):
    return runs.get(name, {}).get("test_psnr")


one = [p for p in (psnr(f"q1_s{seed}") for seed in seeds) if p is not None]
two = [p for p in (psnr(f"q2_s{seed}") for seed in seeds) if p is not None]
quality = {"seeds": seeds, "psnr_1gpu": one, "psnr_2gpu": two}
if len(one) >= 2:
    quality["seed_spread_1gpu"] = [min(one), max(one)]
if one and two:
    quality["mean_2gpu_minus_mean_1gpu"] = statistics.mean(two) - statistics.mean(one)
walls = {}
for seed in ("s" + seed for seed in seeds):
    a, b = runs.get("q1_" + seed, {}), runs.get("q2_" + seed, {})
    if a.get("wall_s") and b.get("wall_s"):
        walls[seed] = {"wall_ratio": b["wall_s"] / a["wall_s"]}
        fa, fb = (a.get("seconds") or {}).get("fine"), (b.get("seconds") or {}).get("fine")
        if fa and fb:
            walls[seed]["fine_ratio"] = fb / fa
quality["two_over_one"] = walls
summary["quality"] = quality

resume = {}
if psnr("resume_2to1") is not None and psnr("q2_" + first) is not None:
    resume["2gpu_ckpt_on_1gpu_minus_uninterrupted_2gpu"] = psnr("resume_2to1") - psnr("q2_" + first)
if psnr("resume_1to2") is not None and psnr("q1_" + first) is not None:
    resume["1gpu_ckpt_on_2gpu_minus_uninterrupted_1gpu"] = psnr("resume_1to2") - psnr("q1_" + first)
summary["resume"] = resume
print(json.dumps(summary, indent=1))
