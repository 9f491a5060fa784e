#!/usr/bin/env python3
"""A grid of images with titles, as one PNG (for docs/ figures).

    /usr/bin/python3 bench/image_grid.py OUT.png --columns 3 TITLE=IMAGE [TITLE=IMAGE ...]

Images fill the grid row by row; every image is shown at its own aspect ratio.
Needs matplotlib (Debian's python3-matplotlib).
"""
import argparse
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("out")
    parser.add_argument("--columns", type=int, default=2)
    parser.add_argument("--width", type=float, default=4.0, help="inches per column")
    parser.add_argument("panels", nargs="+", metavar="TITLE=IMAGE")
    args = parser.parse_args(argv)
    panels = []
    for p in args.panels:
        if "=" not in p:
            parser.error(f"panel '{p}' is not TITLE=IMAGE")
        title, path = p.rsplit("=", 1)
        panels.append((title, mpimg.imread(path)))
    rows = (len(panels) + args.columns - 1) // args.columns
    h, w = panels[0][1].shape[:2]
    fig, axes = plt.subplots(rows, args.columns, squeeze=False,
                             figsize=(args.width * args.columns, args.width * h / w * rows + 0.35 * rows))
    for ax in axes.flat:
        ax.axis("off")
    for ax, (title, image) in zip(axes.flat, panels):
        ax.imshow(image)
        ax.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(args.out, dpi=100)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
