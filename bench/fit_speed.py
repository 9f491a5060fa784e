#!/usr/bin/env python3
"""Times `atex fit` of two CLI binaries on the same input and budgets, in one run.

Builds nothing: give the two binaries (e.g. the CLI of an earlier commit and of this tree).
For each binary and budget it runs

    atex fit INPUT OUT --budget B --json [FIT_ARGS]

timing the wall seconds of the process, then checks the output (bytes <= budget,
`atex verify`), and with --data evaluates the output's test PSNR with `atex eval` (not
timed). Prints one table and writes the rows as JSON lines (--out).

    python3 bench/fit_speed.py --old /tmp/atex_old --new build/bin/atex \
        --input samples/lego_adaptive_2MiB.atex --budgets 1MB,1.5MB \
        --data ../shared/data/dnerf_lego_tiny/tiny_dnerf_data.npz --repeats 1
"""
import argparse
import hashlib
import json
import os
import resource
import subprocess
import sys
import tempfile
import time


def parse_size(text):
    units = {"": 1, "B": 1, "KB": 1000, "MB": 1000**2, "GB": 1000**3, "KIB": 1024, "MIB": 1024**2,
             "GIB": 1024**3, "K": 1024, "M": 1024**2, "G": 1024**3}
    t = text.strip().upper()
    number = t.rstrip("KMGIB ")
    unit = t[len(number):].strip()
    return int(float(number) * units[unit])


def run_fit(binary, input_path, output, budget, fit_args, threads=0):
    """Wall seconds, CPU seconds (user + system, less sensitive to a shared machine) and the report.

    threads > 0 sets OMP_NUM_THREADS for the fit (0: the environment's)."""
    cmd = [binary, "fit", input_path, output, "--budget", budget, "--json"] + fit_args
    env = dict(os.environ)
    if threads > 0:
        env["OMP_NUM_THREADS"] = str(threads)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.monotonic()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    seconds = time.monotonic() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    return seconds, cpu, json.loads(proc.stdout)


def verify(binary, path):
    return subprocess.run([binary, "verify", path], capture_output=True, text=True).returncode == 0


def test_psnr(binary, path, data):
    proc = subprocess.run([binary, "eval", path, "--data", data, "--json"], capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"atex eval {path} failed:\n{proc.stderr[-2000:]}")
    report = json.loads(proc.stdout)
    mean = report.get("mean", report)
    return mean.get("psnr")


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--old", required=True, help="the baseline atex binary")
    p.add_argument("--new", required=True, help="the atex binary under test")
    p.add_argument("--input", default="samples/lego_adaptive_2MiB.atex")
    p.add_argument("--budgets", default="1MB", help="comma-separated budgets, as atex fit reads them")
    p.add_argument("--data", default="", help="dataset for the outputs' test PSNR (atex eval), optional")
    p.add_argument("--repeats", type=int, default=1, help="fits per binary and budget (alternating old/new)")
    p.add_argument("--fit-args", default="", help="extra arguments for atex fit (one string)")
    p.add_argument("--threads", type=int, default=0,
                   help="OMP_NUM_THREADS for the fits (default 0: as the environment sets it)")
    p.add_argument("--out", default="", help="JSON lines of the rows")
    a = p.parse_args()

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for budget in a.budgets.split(","):
            for r in range(a.repeats):
                for label, binary in (("old", a.old), ("new", a.new)):
                    out = os.path.join(tmp, f"{label}_{budget}_{r}.atex")
                    load_before = os.getloadavg()[0]
                    seconds, cpu, report = run_fit(binary, a.input, out, budget, a.fit_args.split(), a.threads)
                    load_after = os.getloadavg()[0]
                    size = os.path.getsize(out)
                    with open(out, "rb") as f:
                        digest = hashlib.sha256(f.read()).hexdigest()
                    timing = report.get("plan_timing", [{}])[0]
                    row = {"binary": label, "path": binary, "budget": budget, "budget_bytes": parse_size(budget),
                           "repeat": r, "threads": a.threads or os.environ.get("OMP_NUM_THREADS", "default"),
                           "cores": os.cpu_count(),
                           "wall_s": round(seconds, 3), "cpu_s": round(cpu, 3), "bytes": size,
                           "within_budget": size <= parse_size(budget), "verify": verify(a.new, out),
                           "measurements": timing.get("measurements"),
                           "plan_s": timing.get("seconds", {}).get("total"),
                           "render_s": timing.get("seconds", {}).get("render"),
                           "gaussians": report["levers"]["gaussians"]["after"],
                           "moves": len(report.get("moves", [])),
                           "proxy_psnr": report.get("estimated_psnr_vs_input"),
                           "sha256": digest, "load_1min_before": round(load_before, 2),
                           "load_1min_after": round(load_after, 2)}
                    if a.data:
                        row["test_psnr"] = test_psnr(a.new, out, a.data)
                    rows.append(row)
                    print(json.dumps(row), file=sys.stderr)
    # The same budget's outputs of the two binaries: byte-identical or not.
    for row in rows:
        pair = [o for o in rows if o["budget"] == row["budget"] and o["repeat"] == row["repeat"]]
        row["same_file_as_old"] = all(o["sha256"] == pair[0]["sha256"] for o in pair)
    header = ["binary", "budget", "wall_s", "cpu_s", "plan_s", "render_s", "measurements", "bytes", "within_budget",
              "verify", "gaussians", "moves", "proxy_psnr"] + (["test_psnr"] if a.data else []) + \
             ["same_file_as_old", "load_1min_before", "load_1min_after"]
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    for row in rows:
        cells = []
        for h in header:
            v = row.get(h)
            cells.append(f"{v:.3f}" if isinstance(v, float) else str(v))
        print("| " + " | ".join(cells) + " |")
    if a.out:
        with open(a.out, "w") as f:
            for row in rows:
                f.write(json.dumps(row) + "\n")
    bad = [r for r in rows if not (r["within_budget"] and r["verify"])]
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
