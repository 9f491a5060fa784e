#!/usr/bin/env python3
"""A contact sheet of test frames: for each camera, one row of ground truth and one row per model,
one column per frame (the PNGs of bench/device/contact_frames.sh).

    /usr/bin/python3 bench/contact_sheet.py --model NAME=DIR [--model NAME=DIR ...] --camera 0 [--camera 10]
                                            --out docs/sheet.png [--title TEXT]
Each DIR holds c<camera>_t<timestep>.png and c<camera>_t<timestep>_gt.png (the ground truth is
taken from the first model's folder). Needs matplotlib (Debian python3-matplotlib).
"""
import argparse
import os
import re
import sys


def frames(folder, camera):
    """Sorted timesteps of a camera's renders in folder."""
    pattern = re.compile(r"^c%d_t(\d+)\.png$" % camera)
    return sorted(int(m.group(1)) for m in (pattern.match(n) for n in os.listdir(folder)) if m)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--model", action="append", required=True, help="NAME=DIR (repeatable; rows in this order)")
    p.add_argument("--camera", action="append", type=int, required=True, help="test camera id (repeatable)")
    p.add_argument("--out", required=True)
    p.add_argument("--title", default="")
    p.add_argument("--width", type=float, default=1.6, help="inches per frame")
    args = p.parse_args(argv)
    models = []
    for spec in args.model:
        name, sep, folder = spec.partition("=")
        if not sep or not os.path.isdir(folder):
            print("contact_sheet: --model %r is not NAME=DIR with an existing DIR" % spec, file=sys.stderr)
            return 2
        models.append((name, folder))
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.image as mpimg
        import matplotlib.pyplot as plt
    except ImportError:
        print("contact_sheet: needs matplotlib (Debian python3-matplotlib)", file=sys.stderr)
        return 3
    rows = []  # (label, [paths])
    columns = 0
    for camera in args.camera:
        steps = frames(models[0][1], camera)
        if not steps:
            print("contact_sheet: no frames of camera %d in %s" % (camera, models[0][1]), file=sys.stderr)
            return 2
        columns = max(columns, len(steps))
        rows.append(("camera %d: ground truth" % camera,
                     [os.path.join(models[0][1], "c%d_t%d_gt.png" % (camera, t)) for t in steps], steps))
        for name, folder in models:
            rows.append(("camera %d: %s" % (camera, name),
                         [os.path.join(folder, "c%d_t%d.png" % (camera, t)) for t in steps], steps))
    first = mpimg.imread(rows[0][1][0])
    aspect = first.shape[0] / first.shape[1]
    fig, axes = plt.subplots(len(rows), columns, figsize=(args.width * columns, args.width * aspect * len(rows) + 0.6),
                             squeeze=False)
    for r, (label, paths, steps) in enumerate(rows):
        for c in range(columns):
            ax = axes[r][c]
            ax.set_xticks([])
            ax.set_yticks([])
            if c < len(paths) and os.path.exists(paths[c]):
                ax.imshow(mpimg.imread(paths[c]))
            if r == 0 or rows[r - 1][0].split(":")[0] != label.split(":")[0]:
                ax.set_title("t=%d" % steps[c] if c < len(steps) else "", fontsize=7)
            if c == 0:
                ax.set_ylabel(label, fontsize=7, rotation=0, ha="right", va="center")
    if args.title:
        fig.suptitle(args.title, fontsize=10)
    fig.tight_layout(pad=0.3)
    fig.savefig(args.out, dpi=100)
    print(args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
