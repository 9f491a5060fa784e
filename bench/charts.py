#!/usr/bin/env python3
"""PNG charts from bench/run_matrix.py results (results.csv).

    /usr/bin/python3 bench/charts.py RESULTS.csv [MORE.csv ...] [--out docs/charts] [--prefix NAME_]
                                     [--variant full] [--seed N | --mean-seeds] [--budgets REGEX]
                                     [--charts size,fps,time,histogram] [--title TEXT]

Needs matplotlib (Debian python3-matplotlib, i.e. /usr/bin/python3); exits with status 3 and a
message when it is missing. Rows whose status is not "ok" are left out (and counted on stderr).
Writes, one panel per dataset where it applies:
  <prefix>psnr_vs_model_mib.png    PSNR vs model size (file MiB): one line per method through its
                                   fixed-budget points (budget kind full/budget); fixed-count
                                   points (keep_count) as crosses
  <prefix>psnr_vs_fps.png          PSNR vs render FPS, at the dataset resolution and at every other
                                   measured size (e.g. 1352x1014)
  <prefix>psnr_vs_train_time.png   PSNR vs training time (stage 1 + stage 2 + fit, minutes)
  <prefix>texel_histogram.png      texel-size histogram (h x w) per scene for the textured methods
                                   at their full budget, with texel bytes per Gaussian vs uniform 4x4
With --metric dynamic_psnr the first three charts show the dynamic-region PSNR instead
(<prefix>dynamic_psnr_vs_*.png; rows without it are left out of those points).
Only rows of --variant (default "full") are drawn when that variant is present, and with --seed
only that seed's rows (a matrix of several seeds would otherwise join them in one line). With
--mean-seeds each (dataset, method, budget) becomes one point, PSNR and MiB averaged over the seeds,
kept only where every seed of the file has that cell (the size chart only: nothing else is averaged). --budgets draws only the budgets whose name
matches the regular expression (one protocol per chart); --charts writes only the named charts.
"""

import argparse
import csv
import math
import os
import re
import sys
import textwrap

HIST_KEYS = ["%dx%d" % (h, w) for h in (1, 2, 4) for w in (1, 2, 4)]
METHOD_ORDER = ["none", "uniform", "adaptive", "no-temporal-peak", "no-anisotropic", "no-visibility-normalization"]
# --metric: the y axis of the size, fps and time charts (dynamic_psnr: atex/dynamic_region.h).
METRIC_LABELS = {"psnr": "test PSNR (dB)", "dynamic_psnr": "test dynamic-region PSNR (dB)"}
LABELS = {"none": "4DGS (no textures)", "uniform": "uniform 4x4", "adaptive": "adaptive (AdaTex4D)"}


def number(text):
    try:
        v = float(text)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def read_rows(paths):
    rows, skipped = [], 0
    for path in paths:
        with open(path, newline="") as f:
            for r in csv.DictReader(f):
                if r.get("status") != "ok" or number(r.get("psnr")) is None:
                    skipped += 1
                    continue
                rows.append(r)
    return rows, skipped


def mean_over_seeds(rows):
    """One row per (dataset, variant, method, budget) that every seed of `rows` has: the first
    seed's row with psnr, dynamic_psnr and model_mib replaced by their means."""
    seeds = {r.get("seed") for r in rows}
    groups = {}
    for r in rows:
        groups.setdefault((r["dataset"], r.get("variant"), r["method"], r.get("budget")), []).append(r)
    out = []
    for group in groups.values():
        if {r.get("seed") for r in group} != seeds:
            continue
        row = dict(group[0])
        for key in ("psnr", "dynamic_psnr", "model_mib"):
            values = [number(r.get(key)) for r in group]
            row[key] = "" if None in values else repr(sum(values) / len(values))
        row["seed"] = "mean of %d" % len(seeds)
        out.append(row)
    return out


def method_sort_key(m):
    return (METHOD_ORDER.index(m) if m in METHOD_ORDER else len(METHOD_ORDER), m)


def grid(plt, n, width=5.2, height=4.0, cols=None):
    cols = cols or min(n, 3)
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(width * cols, height * rows), squeeze=False)
    flat = [a for row in axes for a in row]
    for a in flat[n:]:
        a.set_visible(False)
    return fig, flat[:n]


def no_data(ax, what):
    ax.text(0.5, 0.5, "no %s in the results" % what, ha="center", va="center", transform=ax.transAxes, color="0.4")


class Charts:
    def __init__(self, plt, rows, out, prefix, title, metric="psnr"):
        self.metric = metric  # the y axis of the size, fps and time charts
        self.ylabel = METRIC_LABELS[metric]
        self.plt = plt
        self.rows = rows
        self.out = out
        self.prefix = prefix
        self.title = title
        self.datasets = sorted({r["dataset"] for r in rows}) or ["(none)"]
        self.methods = sorted({r["method"] for r in rows}, key=method_sort_key)
        cmap = plt.get_cmap("tab10")
        self.color = {m: cmap(i % 10) for i, m in enumerate(self.methods)}
        self.written = []

    def save(self, fig, name, suptitle):
        # Wrapped: a single panel is narrower than a long title.
        width = max(40, int(fig.get_figwidth() * 11))
        fig.suptitle(textwrap.fill(suptitle + (" - " + self.title if self.title else ""), width), fontsize=11)
        fig.tight_layout()
        path = os.path.join(self.out, self.prefix + name)
        fig.savefig(path, dpi=110)
        self.plt.close(fig)
        self.written.append(path)

    def label(self, m):
        return LABELS.get(m, m)

    def psnr_vs_size(self):
        fig, axes = grid(self.plt, len(self.datasets))
        for ax, ds in zip(axes, self.datasets):
            drawn = False
            for m in self.methods:
                rs = [r for r in self.rows if r["dataset"] == ds and r["method"] == m]
                line = sorted(((number(r["model_mib"]), number(r.get(self.metric)), r["budget"]) for r in rs
                               if r.get("budget_kind", "full") in ("full", "budget")
                               and number(r.get("model_mib")) is not None and number(r.get(self.metric)) is not None),
                              key=lambda t: t[0])
                if line:
                    ax.plot([p[0] for p in line], [p[1] for p in line], "o-", color=self.color[m], label=self.label(m))
                    for x, y, b in line:
                        ax.annotate(b, (x, y), textcoords="offset points", xytext=(3, 3), fontsize=7, color="0.3")
                    drawn = True
                counts = [(number(r["model_mib"]), number(r.get(self.metric)), r["budget"]) for r in rs
                          if r.get("budget_kind") == "keep_count" and number(r.get("model_mib")) is not None
                          and number(r.get(self.metric)) is not None]
                if counts:
                    ax.plot([p[0] for p in counts], [p[1] for p in counts], "x", color=self.color[m], markersize=8,
                            label=self.label(m) + ", fixed count")
                    for x, y, b in counts:
                        ax.annotate(b, (x, y), textcoords="offset points", xytext=(3, -9), fontsize=7, color="0.3")
                    drawn = True
            if not drawn:
                no_data(ax, "model sizes")
            ax.set_title(ds)
            ax.set_xlabel("model size (MiB, file bytes)")
            ax.set_ylabel(self.ylabel)
            ax.grid(alpha=0.3)
            if drawn:
                ax.legend(fontsize=7)
        self.save(fig, self.metric + "_vs_model_mib.png", self.ylabel + " vs model size (fixed-budget points)")

    def psnr_vs_fps(self):
        sizes = ["fps_native"] + sorted({k for r in self.rows for k in r if k.startswith("fps_") and k != "fps_native"})
        panels = [(ds, s) for ds in self.datasets for s in sizes]
        fig, axes = grid(self.plt, len(panels), cols=len(sizes))
        for ax, (ds, col) in zip(axes, panels):
            drawn = False
            for m in self.methods:
                pts = [(number(r.get(col)), number(r.get(self.metric)), r["budget"]) for r in self.rows
                       if r["dataset"] == ds and r["method"] == m and number(r.get(col))
                       and number(r.get(self.metric)) is not None]
                if pts:
                    ax.scatter([p[0] for p in pts], [p[1] for p in pts], color=self.color[m], label=self.label(m), s=22)
                    drawn = True
            native = next((r.get("native_size") for r in self.rows if r["dataset"] == ds and r.get("native_size")), "")
            size = native if col == "fps_native" else col[len("fps_"):]
            ax.set_title("%s at %s" % (ds, size or "dataset resolution"))
            ax.set_xlabel("render FPS (deformation included)")
            ax.set_ylabel(self.ylabel)
            ax.grid(alpha=0.3)
            if drawn:
                ax.set_xscale("log")
                ax.legend(fontsize=7)
            else:
                no_data(ax, "FPS measurements")
        self.save(fig, self.metric + "_vs_fps.png", self.ylabel + " vs render speed")

    def psnr_vs_time(self):
        fig, axes = grid(self.plt, len(self.datasets))
        for ax, ds in zip(axes, self.datasets):
            drawn = False
            for m in self.methods:
                pts = [(number(r.get("train_s_total")) / 60.0, number(r.get(self.metric)), r["budget"])
                       for r in self.rows if r["dataset"] == ds and r["method"] == m and number(r.get("train_s_total"))
                       and number(r.get(self.metric)) is not None]
                if pts:
                    ax.scatter([p[0] for p in pts], [p[1] for p in pts], color=self.color[m], label=self.label(m), s=22)
                    drawn = True
            ax.set_title(ds)
            ax.set_xlabel("training time, stage 1 + stage 2 + fit (min)")
            ax.set_ylabel(self.ylabel)
            ax.grid(alpha=0.3)
            if drawn:
                ax.legend(fontsize=7)
            else:
                no_data(ax, "training times")
        self.save(fig, self.metric + "_vs_train_time.png", self.ylabel + " vs training time")

    def texel_histogram(self):
        fig, axes = grid(self.plt, len(self.datasets), width=6.0)
        for ax, ds in zip(axes, self.datasets):
            rs = [r for r in self.rows if r["dataset"] == ds and r.get("budget") == "full" and number(r.get("texels"))]
            rs.sort(key=lambda r: method_sort_key(r["method"]))
            if not rs:
                no_data(ax, "textured models")
                ax.set_title(ds)
                continue
            width = 0.8 / len(rs)
            for i, r in enumerate(rs):
                counts = [number(r.get("hist_" + k)) or 0 for k in HIST_KEYS]
                total = sum(counts) or 1
                xs = [j + (i - (len(rs) - 1) / 2.0) * width for j in range(len(HIST_KEYS))]
                label = self.label(r["method"])
                g = number(r.get("gaussians")) or 0
                tb, ub = number(r.get("texel_bytes")), number(r.get("uniform_texel_bytes"))
                if g > 0 and tb is not None and ub:
                    label += ": %.0f B/Gaussian vs uniform %.0f (%.0f%%)" % (tb / g, ub / g, 100.0 * tb / ub)
                ax.bar(xs, [c / total for c in counts], width=width, color=self.color[r["method"]], label=label)
            ax.set_xticks(range(len(HIST_KEYS)))
            ax.set_xticklabels(HIST_KEYS)
            ax.set_xlabel("texture size h x w (texels)")
            ax.set_ylabel("fraction of Gaussians")
            ax.set_title(ds)
            ax.grid(alpha=0.3, axis="y")
            ax.set_ylim(0, 1.0 + 0.09 * len(rs))  # room for the legend above the bars
            ax.legend(fontsize=7, loc="upper left")
        self.save(fig, "texel_histogram.png", "Texel-size histogram (texel bytes per Gaussian vs uniform 4x4)")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("csv", nargs="+", help="results.csv file(s) of bench/run_matrix.py")
    p.add_argument("--out", default=os.path.join("docs", "charts"), help="output folder (default docs/charts)")
    p.add_argument("--prefix", default="", help="file name prefix, e.g. panoptic_")
    p.add_argument("--variant", default="full", help="draw only this variant when present (default full)")
    p.add_argument("--seed", default="", help="draw only this seed's rows (default: every seed)")
    p.add_argument("--mean-seeds", action="store_true",
                   help="average PSNR and MiB over the seeds (cells every seed has)")
    p.add_argument("--budgets", default="", help="draw only budgets whose name matches this regex")
    p.add_argument("--charts", default="size,fps,time,histogram",
                   help="which charts, comma-separated (default: size,fps,time,histogram)")
    p.add_argument("--title", default="", help="appended to every chart title")
    p.add_argument("--metric", default="psnr", choices=sorted(METRIC_LABELS),
                   help="y axis of the size, fps and time charts (default psnr; dynamic_psnr: the dynamic region's)")
    args = p.parse_args(argv)
    chosen = [c for c in args.charts.split(",") if c]
    unknown = [c for c in chosen if c not in ("size", "fps", "time", "histogram")]
    if unknown or not chosen:
        print("charts: --charts takes size, fps, time, histogram (got %r)" % args.charts, file=sys.stderr)
        return 2
    if args.seed and args.mean_seeds:
        print("charts: --seed and --mean-seeds are alternatives", file=sys.stderr)
        return 2
    if args.mean_seeds and chosen != ["size"]:  # only PSNR and MiB are averaged
        print("charts: --mean-seeds draws the size chart only (--charts size)", file=sys.stderr)
        return 2
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("charts: matplotlib is not installed for %s (Debian: apt-get install python3-matplotlib, "
              "then run /usr/bin/python3 bench/charts.py)" % sys.executable, file=sys.stderr)
        return 3
    try:
        rows, skipped = read_rows(args.csv)
    except OSError as e:
        print("charts: %s" % e, file=sys.stderr)
        return 2
    if any(r.get("variant") == args.variant for r in rows):
        rows = [r for r in rows if r.get("variant") == args.variant]
    if args.seed:
        rows = [r for r in rows if str(r.get("seed")) == args.seed]
        if not rows:
            print("charts: no drawable rows of seed %s" % args.seed, file=sys.stderr)
            return 2
    if args.budgets:
        try:
            pattern = re.compile(args.budgets)
        except re.error as e:
            print("charts: --budgets: %s" % e, file=sys.stderr)
            return 2
        rows = [r for r in rows if pattern.search(r.get("budget", ""))]
    if args.mean_seeds:
        rows = mean_over_seeds(rows)
    if (args.budgets or args.mean_seeds) and not rows:
        print("charts: no drawable rows left (--budgets / --mean-seeds)", file=sys.stderr)
        return 2
    if skipped:
        print("charts: %d row(s) left out (failed or without PSNR)" % skipped, file=sys.stderr)
    os.makedirs(args.out, exist_ok=True)
    charts = Charts(plt, rows, args.out, args.prefix, args.title, args.metric)
    for name, draw in (("size", charts.psnr_vs_size), ("fps", charts.psnr_vs_fps), ("time", charts.psnr_vs_time),
                       ("histogram", charts.texel_histogram)):
        if name in chosen:
            draw()
    for path in charts.written:
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
