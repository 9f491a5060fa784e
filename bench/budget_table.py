#!/usr/bin/env python3
"""Markdown tables of a budget matrix (bench/run_matrix.py results.csv) over its seeds.

    python3 bench/budget_table.py RESULTS.csv [--budgets full,p25,...] [--baseline uniform] [--method adaptive]
                                  [--variant NAME] [--dataset NAME]

Prints two tables:
  1. per budget and method: test PSNR, its mean over the seeds that have the cell, the means of
     SSIM, DSSIM1 and DSSIM2, file MiB, the Gaussians kept (mean over seeds, and as a share of
     the same seed's unfitted model), the texels kept (mean) and the fit's seconds (min-max);
  2. per budget: METHOD - BASELINE test PSNR for each seed that has both cells, and their mean.
A file of several datasets or variants needs --dataset/--variant to pick one (the cells of
different variants are different models: averaging them would be wrong, so it is an error).
Budgets come in the order given (default: the order of first appearance in the file), methods in
charts.py's order. Rows are read as charts.py reads them (not "ok" or without PSNR: left out). The confidence intervals are bench/paired_bootstrap.py's.
"""

import argparse
import sys

from charts import method_sort_key, number, read_rows


def mean(values):
    return sum(values) / len(values) if values else None


def tables(rows, budgets, baseline, method):
    seeds = []
    for r in rows:
        if r["seed"] not in seeds:
            seeds.append(r["seed"])
    methods = sorted({r["method"] for r in rows}, key=method_sort_key)
    cell = {(r["budget"], r["method"], r["seed"]): r for r in rows}
    out = ["| budget | method | test PSNR, mean | per seed (%s) | SSIM | DSSIM1 | DSSIM2 | file MiB, mean "
           "| Gaussians kept, mean | of the unfitted model | texels, mean | fit s |" % ", ".join(seeds),
           "|---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for b in budgets:
        for m in methods:
            rs = [(s, cell[(b, m, s)]) for s in seeds if (b, m, s) in cell]
            if not rs:
                continue
            shares = [number(r["gaussians"]) / number(cell[("full", m, s)]["gaussians"]) for s, r in rs
                      if ("full", m, s) in cell and number(r.get("gaussians")) and
                      number(cell[("full", m, s)].get("gaussians"))]
            per_seed = ", ".join("%.3f" % number(cell[(b, m, s)]["psnr"]) if (b, m, s) in cell else "-"
                                 for s in seeds)
            gaussians = mean([number(r["gaussians"]) for _, r in rs if number(r.get("gaussians")) is not None])
            structure = []
            for key in ("ssim", "dssim1", "dssim2"):
                values = [number(r.get(key)) for _, r in rs]
                structure.append("-" if None in values else "%.4f" % mean(values))
            texels = [number(r.get("texels")) for _, r in rs]
            fit_s = [number(r.get("fit_s")) for _, r in rs if number(r.get("fit_s")) is not None]
            out.append("| %s | %s | %.3f | %s | %s | %.2f | %s | %s | %s | %s |" % (
                b, m, mean([number(r["psnr"]) for _, r in rs]), per_seed, " | ".join(structure),
                mean([number(r["model_mib"]) for _, r in rs]),
                "%.0f" % gaussians if gaussians is not None else "-",
                "%.1f %%" % (100 * mean(shares)) if shares else "-",
                "-" if None in texels else "%.0f" % mean(texels),
                "%.1f-%.1f" % (min(fit_s), max(fit_s)) if fit_s else "-"))
    out += ["", "| budget | %s - %s, per seed (%s) | mean | seeds |" % (method, baseline, ", ".join(seeds)),
            "|---|---|---:|---:|"]
    for b in budgets:
        diffs = {s: number(cell[(b, method, s)]["psnr"]) - number(cell[(b, baseline, s)]["psnr"])
                 for s in seeds if (b, method, s) in cell and (b, baseline, s) in cell}
        if not diffs:
            continue
        out.append("| %s | %s | %+.3f | %d |" % (
            b, ", ".join("%+.3f" % diffs[s] if s in diffs else "-" for s in seeds), mean(list(diffs.values())),
            len(diffs)))
    return "\n".join(out)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("csv", help="results.csv of bench/run_matrix.py")
    p.add_argument("--budgets", default="", help="comma-separated budget names, in table order (default: all)")
    p.add_argument("--baseline", default="uniform")
    p.add_argument("--method", default="adaptive")
    p.add_argument("--variant", default="", help="the variant whose cells to tabulate (needed when there are several)")
    p.add_argument("--dataset", default="", help="the dataset whose cells to tabulate (needed when there are several)")
    args = p.parse_args(argv)
    try:
        rows, _ = read_rows([args.csv])
    except OSError as e:
        print("budget_table: %s" % e, file=sys.stderr)
        return 2
    for key in ("dataset", "variant"):
        wanted = getattr(args, key)
        if wanted:
            rows = [r for r in rows if r.get(key, "") == wanted]
            if not rows:
                print("budget_table: no rows of %s %r in %s" % (key, wanted, args.csv), file=sys.stderr)
                return 2
        names = sorted({r.get(key, "") for r in rows})
        if len(names) > 1:
            print("budget_table: %s holds the %ss %s: pick one with --%s" % (args.csv, key, ", ".join(names), key),
                  file=sys.stderr)
            return 2
    budgets = [b for b in args.budgets.split(",") if b]
    if not budgets:
        for r in rows:
            if r["budget"] not in budgets:
                budgets.append(r["budget"])
    print(tables(rows, budgets, args.baseline, args.method))
    return 0


if __name__ == "__main__":
    sys.exit(main())
