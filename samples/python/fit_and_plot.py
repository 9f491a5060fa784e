#!/usr/bin/env python3
"""The bundled lego sample from Python: read it, render three times, fit it to 1 MiB (and a
few sizes between, from one plan), and plot PSNR against file size with matplotlib.

  PYTHONPATH=build/python python3 samples/python/fit_and_plot.py [--data ../shared/data/dnerf_lego_tiny/tiny_dnerf_data.npz]
      [--out out/python_sample]

With --data (the tiny D-NeRF lego), the renders use its test cameras and PSNR is measured on its
test views (atex.eval); without it, orbit cameras and the fitter's proxy PSNR against the
unfitted renders. Writes renders_<t>.png, lego_1MiB.atex and psnr_vs_size.png into --out.
"""

import argparse
import os
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import atex  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[2]


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--asset", default=str(ROOT / "samples" / "lego_adaptive_2MiB.atex"))
    parser.add_argument("--data", default=None, help="the tiny lego .npz (PSNR on its test views)")
    parser.add_argument("--out", default="out/python_sample")
    parser.add_argument("--backend", default="auto")
    parser.add_argument("--probes", type=int, default=4, help="probe views of the fit (atex fit's default: 8)")
    parser.add_argument("--probe-size", type=int, default=96, help="longer side of the probe renders (default 256)")
    args = parser.parse_args()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    asset = atex.read(args.asset)
    print(f"atex {atex.__version__}: {asset}, {os.path.getsize(args.asset)} bytes")
    dataset = atex.Dataset(args.data) if args.data else None

    # Three renders across the scene's time range.
    t0, t1 = asset.time_range
    figure, axes = plt.subplots(1, 3, figsize=(9, 3.2))
    for ax, t in zip(axes, np.linspace(t0, t1, 3)):
        if dataset:
            view = min(dataset.test_views, key=lambda v: abs(v.camera.time - t))
            camera = view.camera
        else:
            camera = atex.orbit_camera(asset, width=200, height=150, t=float(t))
        image = atex.render(asset, camera, t=float(t), backend=args.backend)
        ax.imshow(np.clip(image, 0, 1))
        ax.set_title(f"t = {t:.2f}")
        ax.axis("off")
    figure.tight_layout()
    figure.savefig(out / "renders.png", dpi=100)

    # One plan, several budgets: 1 MiB and sizes up to the input's.
    budgets = [1 << 20, 1280 * 1024, 1536 * 1024, 1792 * 1024]
    fits = atex.fit(asset, budget=budgets, dataset=dataset, backend=args.backend, probes=args.probes,
                    probe_size=args.probe_size,
                    progress=lambda p: print("  fit:", p["text"]))
    sizes, psnrs = [], []
    for budget, (fitted, report) in zip(budgets, fits):
        if dataset:
            psnr = atex.eval(fitted, dataset, backend=args.backend)["mean"]["psnr"]
        else:
            # Absent when the output is the levers' smallest asset (report["smallest_fallback"]).
            psnr = report.get("estimated_psnr_vs_input", float("nan"))
        sizes.append(report["bytes"] / 2**20)
        psnrs.append(psnr)
        print(f"budget {budget / 2**20:.2f} MiB: {report['bytes']} bytes, {fitted.gaussian_count} Gaussians, "
              f"PSNR {psnr:.2f} dB")
    fits[0][0].write(str(out / "lego_1MiB.atex"))
    if dataset:
        sizes.append(os.path.getsize(args.asset) / 2**20)
        psnrs.append(atex.eval(asset, dataset, backend=args.backend)["mean"]["psnr"])

    figure, ax = plt.subplots(figsize=(5, 3.5))
    ax.plot(sizes, psnrs, "o-")
    ax.set_xlabel("file size (MiB)")
    ax.set_ylabel("test PSNR (dB)" if dataset else "proxy PSNR vs. the input (dB)")
    ax.set_title("lego sample fitted with atex.fit")
    ax.grid(True, alpha=0.3)
    figure.tight_layout()
    figure.savefig(out / "psnr_vs_size.png", dpi=100)
    print(f"wrote {out / 'renders.png'}, {out / 'psnr_vs_size.png'}, {out / 'lego_1MiB.atex'}")


if __name__ == "__main__":
    main()
