#!/usr/bin/env python3
"""PSNR of assets against a reference asset, rendered from orbit views (the Python module).

    PYTHONPATH=build/python python3 bench/psnr_orbit_views.py REFERENCE.atex FITTED.atex...

Renders the reference and each other asset from 24 orbit views (azimuths 15..345 degrees in
steps of 30, elevations 10 and 35 degrees, 320x240, at time 0) on the CPU backend, clamps to
[0, 1] and prints one line per asset: its path and the PSNR of the mean squared difference over
all views. The views are not `atex fit`'s orbit probes (other azimuths and elevations), so a fit
is judged on views it did not measure.
"""
import argparse

import numpy as np

import atex


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("reference")
    p.add_argument("assets", nargs="+")
    p.add_argument("--backend", default="cpu", help="atex.render backend (cpu, cuda, auto)")
    a = p.parse_args()
    ref = atex.read(a.reference)
    cams = [atex.orbit_camera(ref, azimuth_deg=az, elevation_deg=el, width=320, height=240)
            for az in range(15, 360, 30) for el in (10, 35)]
    refs = [np.clip(atex.render(ref, c, backend=a.backend), 0, 1) for c in cams]
    for path in a.assets:
        asset = atex.read(path)
        mse = np.mean([np.mean((np.clip(atex.render(asset, c, backend=a.backend), 0, 1) - r) ** 2)
                       for c, r in zip(cams, refs)])
        print(path, f"{-10 * np.log10(mse):.3f}")


if __name__ == "__main__":
    main()
