#!/usr/bin/env python3
"""The stage-2 growth probes of BENCHMARKS.md (stage 2, seventh run): collect and summarise.

    python3 bench/growth_probes.py collect out/probe2 out/probe3 --out PROBES.json
    python3 bench/growth_probes.py summary PROBES.json --rows SEEDS.jsonl [--dataset basketball] [--variant full]
                                      [--samples 10000]

`collect` gathers what bench/device/growth_probes.sh wrote (NAME.train.json, NAME.eval.json and,
where present, NAME.evaltrain.json and NAME.info.json) into one file, keyed "PROBE/NAME". The
training-view evaluation keeps its mean and cameras, the train report's final test evaluation its
mean: the per-view test rows are in "eval".
`summary` prints each probe's test PSNR against the uniform row (cell DATASET/VARIANT/sSEED/uniform/full,
SEED from the probe's name "sSEED_...") in the matrix rows (bench/run_matrix.py's results.jsonl; the 2,500-step probes against their own uniform
run), with paired bootstrap 95 % intervals over the test views (bench/paired_bootstrap.py).
Python 3 standard library only.
"""

import argparse
import glob
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import paired_bootstrap  # noqa: E402


def collect(dirs, out):
    runs = {}
    for d in dirs:
        for train in sorted(glob.glob(os.path.join(d, "*.train.json"))):
            stem = train[:-len(".train.json")]
            run = {"train": json.load(open(train))}
            for key, suffix in (("eval", ".eval.json"), ("eval_train", ".evaltrain.json"), ("info", ".info.json")):
                if os.path.exists(stem + suffix):
                    run[key] = json.load(open(stem + suffix))
            if "eval_train" in run:
                run["eval_train"].pop("views", None)
            test = run["train"].get("test")
            if isinstance(test, dict):
                test.pop("views", None)
            runs["%s/%s" % (os.path.basename(os.path.normpath(d)), os.path.basename(stem))] = run
    with open(out, "w") as f:
        json.dump({"runs": runs}, f, indent=1)
    print("%d runs -> %s" % (len(runs), out))


def difference(base_views, views, samples):
    diffs, _ = paired_bootstrap.pairs(base_views, views, "psnr")
    r = paired_bootstrap.bootstrap(diffs, "view", samples, 6666)
    return "%+.3f [%+.3f, %+.3f]" % (r["mean"], r["ci95"][0], r["ci95"][1]) if r["ci95"] else "%+.3f" % r["mean"]


def summary(path, rows_path, dataset, variant, samples):
    runs = json.load(open(path))["runs"]
    rows = {r["cell"]: r for r in paired_bootstrap.load_rows(rows_path)}
    print("| probe | test PSNR | train PSNR | texels | − uniform (dB, 95 % CI) |")
    print("|---|---|---|---|---|")
    for name, run in sorted(runs.items()):
        probe, stem = name.split("/")
        seed, kind = stem.split("_", 1)
        views = paired_bootstrap.eval_views(run["eval"])
        if probe == "probe3":
            if kind == "uniform":
                continue
            base = paired_bootstrap.eval_views(runs["%s/%s_uniform" % (probe, seed)]["eval"])
        else:
            base = rows["%s/%s/%s/uniform/full" % (dataset, variant, seed)]["views"]
        train = run.get("eval_train", {}).get("mean", {}).get("psnr")
        texels = (run.get("info") or {}).get("textures", {}).get("texels")
        print("| %s | %.3f | %s | %s | %s |" % (name, run["eval"]["mean"]["psnr"],
                                              "%.3f" % train if train is not None else "–",
                                              "{:,}".format(texels) if texels else "–",
                                              difference(base, views, samples)))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True)
    c = sub.add_parser("collect")
    c.add_argument("dirs", nargs="+")
    c.add_argument("--out", required=True)
    s = sub.add_parser("summary")
    s.add_argument("probes")
    s.add_argument("--rows", required=True)
    s.add_argument("--dataset", default="basketball")
    s.add_argument("--variant", default="full")
    s.add_argument("--samples", type=int, default=10000)
    args = p.parse_args(argv)
    try:
        if args.command == "collect":
            collect(args.dirs, args.out)
        else:
            summary(args.probes, args.rows, args.dataset, args.variant, args.samples)
    except (OSError, ValueError, KeyError) as e:
        print("growth_probes: %s" % e, file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
