#!/usr/bin/env python3
"""Paired bootstrap 95% confidence intervals of a PSNR (or SSIM/DSSIM) difference between methods.

    python3 bench/paired_bootstrap.py RESULTS.jsonl --baseline uniform [--method adaptive ...]
                                      [--metric psnr] [--unit view|camera|dataset|seed]
                                      [--samples 10000] [--seed 6666] [--json OUT] [--markdown OUT]
    python3 bench/paired_bootstrap.py --eval-a UNIFORM.eval.json --eval-b ADAPTIVE.eval.json

Python 3 standard library only. Input: the rows of bench/run_matrix.py (results.jsonl; each row
holds the per-view metrics of `atex eval --json`: [camera, timestep, psnr, ssim, dssim1, dssim2]),
or two `atex eval --json` outputs. Rows are compared within a group (dataset, variant, seed,
budget): each method against the baseline, paired on (camera, timestep) - the same test view
rendered by two models trained from the same stage-1 model with the same seed and camera
schedule. The difference reported is method - baseline.

Resampling unit:
  view     (default) the paired views (test cameras x timesteps) are resampled with replacement;
  camera   whole test cameras are resampled (a cluster bootstrap: views of one camera are correlated);
  dataset  whole datasets (scenes) are resampled: pooled over every dataset of the file, as the
           paper's scene-level intervals (needs several datasets).
  seed     whole stage-1 models are resampled: pooled over every seed of a (dataset, variant, budget),
           each method paired with the baseline trained from the same seed's stage-1 model. The
           difference between methods depends on the stage-1 model (BENCHMARKS.md, stage 2), so this is
           the interval of "another training run"; with a handful of seeds it is coarse.
The interval is the percentile interval of the bootstrap means (2.5%, 97.5%); `p_le_0` is the
fraction of bootstrap means <= 0 (a one-sided bootstrap p-value for "method > baseline"). With one
cluster (e.g. --unit seed over one seed) neither exists: the table says so, the JSON has null.
"""

import argparse
import json
import math
import random
import sys

METRICS = {"psnr": 2, "ssim": 3, "dssim1": 4, "dssim2": 5, "dynamic_psnr": 6}  # index in a row's "views" entries


def load_rows(path):
    rows = {}
    with open(path) as f:
        for line in f:
            line = line.strip()
            if line:
                try:
                    row = json.loads(line)
                except ValueError:
                    continue
                rows[row.get("cell")] = row  # the last row of a cell wins (as run_matrix reads it)
    return list(rows.values())


def eval_views(ev):
    """[camera, timestep, psnr, ssim, dssim1, dssim2, dynamic_psnr] rows of an `atex eval --json` output."""
    return [[v.get("camera"), v.get("timestep"), v.get("psnr"), v.get("ssim"), v.get("dssim1"), v.get("dssim2"),
             v.get("dynamic_psnr")] for v in ev.get("views", [])]


def pairs(base_views, method_views, metric, dataset="", seed=None):
    """[(cluster keys, difference)] over the views both have with a finite metric."""
    k = METRICS[metric]
    base = {(v[0], v[1]): (v[k] if len(v) > k else None) for v in base_views}
    out, missing = [], 0
    for v in method_views:
        b = base.get((v[0], v[1]))
        m = v[k] if len(v) > k else None  # rows from before a metric existed lack it
        if isinstance(b, (int, float)) and isinstance(m, (int, float)) and math.isfinite(b) and math.isfinite(m):
            out.append(({"view": (dataset, seed, v[0], v[1]), "camera": (dataset, seed, v[0]), "dataset": dataset,
                         "seed": (dataset, seed)}, m - b))
        else:
            missing += 1
    return out, missing


def bootstrap(diffs, unit, samples, seed):
    """Mean difference, its 95% percentile interval and P(bootstrap mean <= 0); the interval and
    P are None with fewer than two clusters (resampling one cluster only repeats it)."""
    clusters = {}
    for keys, d in diffs:
        clusters.setdefault(keys[unit], []).append(d)
    groups = [(sum(v), len(v)) for v in clusters.values()]
    n = len(groups)
    mean = sum(d for _, d in diffs) / len(diffs)
    if n < 2:
        return {"mean": mean, "ci95": None, "p_le_0": None, "clusters": n}
    rng = random.Random(seed)
    means = []
    for _ in range(samples):
        total, count = 0.0, 0
        for _ in range(n):
            s, c = groups[rng.randrange(n)]
            total += s
            count += c
        means.append(total / count)
    means.sort()

    def pct(q):  # linear interpolation between order statistics
        x = q * (len(means) - 1)
        lo = int(math.floor(x))
        hi = min(lo + 1, len(means) - 1)
        return means[lo] + (means[hi] - means[lo]) * (x - lo)

    return {"mean": mean, "ci95": [pct(0.025), pct(0.975)], "p_le_0": sum(1 for m in means if m <= 0) / samples,
            "clusters": n}


def compare_rows(rows, baseline, methods, metric, unit, samples, seed):
    results = []
    ok_rows = [r for r in rows if r.get("views")]
    any_seed = object()  # unit "seed": a group pools every seed
    if unit == "dataset":
        keys = sorted({(r.get("variant"), r.get("seed"), r.get("budget")) for r in ok_rows}, key=str)
        groups = [(None, k) for k in keys]
    elif unit == "seed":
        keys = sorted({(r.get("dataset"), r.get("variant"), r.get("budget")) for r in ok_rows}, key=str)
        groups = [(k[0], (k[1], any_seed, k[2])) for k in keys]
    else:
        keys = sorted({(r.get("dataset"), r.get("variant"), r.get("seed"), r.get("budget")) for r in ok_rows}, key=str)
        groups = [(k[0], k[1:]) for k in keys]
    for dataset, (variant, seed_, budget) in groups:
        members = [r for r in ok_rows if (dataset is None or r.get("dataset") == dataset) and
                   r.get("variant") == variant and (seed_ is any_seed or r.get("seed") == seed_) and
                   r.get("budget") == budget]
        by_method = {}
        for r in members:
            by_method.setdefault(r.get("method"), []).append(r)
        if baseline not in by_method:
            continue
        targets = methods or sorted(m for m in by_method if m != baseline)
        for m in targets:
            if m not in by_method or m == baseline:
                continue
            diffs, missing = [], 0
            for b in by_method[baseline]:
                for r in by_method[m]:
                    if r.get("dataset") != b.get("dataset") or r.get("seed") != b.get("seed"):
                        continue
                    d, miss = pairs(b["views"], r["views"], metric, r.get("dataset"), r.get("seed"))
                    diffs += d
                    missing += miss
            if not diffs:
                continue
            res = bootstrap(diffs, unit, samples, seed)
            statuses = sorted({r.get("status") for r in by_method[m] + by_method[baseline]})
            seeds = sorted({r.get("seed") for r in by_method[m]} & {b.get("seed") for b in by_method[baseline]}, key=str)
            results.append({"dataset": dataset if dataset is not None else "all", "variant": variant,
                            "seed": ",".join(str(x) for x in seeds),
                            "budget": budget, "method": m, "baseline": baseline, "metric": metric, "unit": unit,
                            "pairs": len(diffs), "unpaired": missing, "samples": samples,
                            "row_status": ",".join(str(s) for s in statuses), **res})
    return results


def markdown(results):
    lines = ["| dataset | variant | seed | budget | method - baseline | metric | pairs | clusters (unit) | mean diff | "
             "95% CI | P(<=0) |", "|---|---|---|---|---|---|---:|---:|---:|---|---:|"]
    for r in results:
        ci = "[%+.4f, %+.4f]" % tuple(r["ci95"]) if r["ci95"] else "none (one cluster)"
        p = "%.4f" % r["p_le_0"] if r["p_le_0"] is not None else "-"
        lines.append("| %s | %s | %s | %s | %s - %s | %s | %d | %d (%s) | %+.4f | %s | %s |" % (
            r["dataset"], r["variant"], r["seed"], r["budget"], r["method"], r["baseline"], r["metric"], r["pairs"],
            r["clusters"], r["unit"], r["mean"], ci, p))
    return "\n".join(lines) + "\n"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("results", nargs="?", help="results.jsonl of bench/run_matrix.py")
    p.add_argument("--baseline", default="uniform", help="baseline method (default uniform)")
    p.add_argument("--method", action="append", default=[], help="method(s) to compare (default: all others)")
    p.add_argument("--metric", default="psnr", choices=sorted(METRICS))
    p.add_argument("--unit", default="view", choices=["view", "camera", "dataset", "seed"])
    p.add_argument("--samples", type=int, default=10000)
    p.add_argument("--seed", type=int, default=6666, help="seed of the resampling (default 6666)")
    p.add_argument("--eval-a", help="baseline `atex eval --json` output (instead of RESULTS)")
    p.add_argument("--eval-b", help="method `atex eval --json` output (instead of RESULTS)")
    p.add_argument("--json", help="write the results as JSON here")
    p.add_argument("--markdown", help="write the table as markdown here")
    args = p.parse_args(argv)
    if args.samples < 100:
        p.error("--samples must be at least 100")
    try:
        if args.eval_a or args.eval_b:
            if not (args.eval_a and args.eval_b):
                p.error("--eval-a and --eval-b go together")
            with open(args.eval_a) as f:
                a = json.load(f)
            with open(args.eval_b) as f:
                b = json.load(f)
            rows = [{"cell": "a", "dataset": "-", "variant": "-", "seed": 0, "budget": "-", "method": "a",
                     "status": "ok", "views": eval_views(a)},
                    {"cell": "b", "dataset": "-", "variant": "-", "seed": 0, "budget": "-", "method": "b",
                     "status": "ok", "views": eval_views(b)}]
            results = compare_rows(rows, "a", ["b"], args.metric, args.unit, args.samples, args.seed)
        else:
            if not args.results:
                p.error("give RESULTS.jsonl or --eval-a/--eval-b")
            rows = load_rows(args.results)
            results = compare_rows(rows, args.baseline, args.method, args.metric, args.unit, args.samples,
                                   args.seed)
    except (OSError, ValueError) as e:
        print("paired_bootstrap: %s" % e, file=sys.stderr)
        return 2
    if not results:
        print("paired_bootstrap: no pairs (no rows with per-view metrics for both the baseline and a method in "
              "the same dataset/variant/seed/budget)", file=sys.stderr)
        return 1
    table = markdown(results)
    sys.stdout.write(table)
    if args.markdown:
        with open(args.markdown, "w") as f:
            f.write(table)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1)
            f.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
