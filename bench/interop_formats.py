#!/usr/bin/env python3
"""Sizes of every splat format libatex reads or writes, for one model, and who checked each.

Writes the shared INRIA 3DGS PLY (../shared/data/splats, 9,080 Gaussians, SH 3) into every
format: third-party writers through tests/splat_transform/make_fixtures.mjs (PlayCanvas
splat-transform: compressed PLY, SOG, SPZ, glTF; gsplat.js: .splat; GaussianSplats3D: .ksplat
levels 0-2) and our own writers (`atex convert`, `atex export`). Every file is then read back by
`atex convert FILE out.ply` (our readers) and the Gaussian count compared. Prints a Markdown
table (bytes and bytes per Gaussian) and writes it with the raw figures as JSON.

Usage: bench/interop_formats.py --atex build/bin/atex [--data ../shared/data] [--out DIR]
Needs node and tests/splat_transform/install.sh.
"""
import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def run(cmd, **kw):
    return subprocess.run(cmd, check=True, capture_output=True, text=True, **kw)


def read_back(atex, path, out_dir):
    """Our reader on `path`: (ok, gaussians or error text)."""
    if path.endswith(".glb"):  # glTF is read by `atex import`
        out = os.path.join(out_dir, "readback.atex")
        r = subprocess.run([atex, "import", path, out], capture_output=True, text=True)
        if r.returncode == 0:
            r = subprocess.run([atex, "convert", out, os.path.join(out_dir, "readback.ply"), "--json"],
                               capture_output=True, text=True)
    else:
        r = subprocess.run([atex, "convert", path, os.path.join(out_dir, "readback.ply"), "--json"],
                           capture_output=True, text=True)
    if r.returncode != 0:
        return False, " ".join((r.stderr or r.stdout).strip().splitlines()[-1:])
    return True, json.loads(r.stdout)["gaussians"]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--atex", required=True, help="the atex command line")
    ap.add_argument("--data", default=os.environ.get("ATEX_DATA_DIR", os.path.join(ROOT, "..", "shared", "data")))
    ap.add_argument("--out", help="keep the files here (default: a temporary folder)")
    ap.add_argument("--json", help="also write the rows as JSON to this file")
    args = ap.parse_args(argv)

    source = os.path.join(args.data, "splats", "kacytran1122_try_iter7000_point_cloud.ply")
    work = args.out or tempfile.mkdtemp(prefix="atex-interop-")
    os.makedirs(work, exist_ok=True)
    writers = os.path.join(ROOT, "tests", "splat_transform")
    print(f"third-party writers into {work} ...", file=sys.stderr)
    run(["node", os.path.join(writers, "make_fixtures.mjs"), source, work])
    cli = os.path.join(writers, "node_modules", "@playcanvas", "splat-transform", "bin", "cli.mjs")
    for name in ("st.spz", "st.glb"):
        run(["node", cli, "-q", "-w", "-g", "cpu", source, os.path.join(work, name)])
    ours = os.path.join(work, "ours")
    os.makedirs(ours, exist_ok=True)
    report = json.loads(run([args.atex, "convert", source, os.path.join(ours, "src.atex"), "--json"]).stdout)
    n = report["gaussians"]
    run([args.atex, "convert", source, os.path.join(ours, "src.spz")])
    run([args.atex, "convert", source, os.path.join(ours, "src.ply")])
    run([args.atex, "export", os.path.join(ours, "src.atex"), os.path.join(ours, "src.glb")])
    run([args.atex, "export", os.path.join(ours, "src.atex"), os.path.join(ours, "src_spz.glb"), "--spz"])
    meshopt = subprocess.run([args.atex, "export", os.path.join(ours, "src.atex"), os.path.join(ours, "src_meshopt.glb"),
                              "--meshopt", "--meshopt-bits", "12"], capture_output=True, text=True).returncode == 0

    rows = [
        ("INRIA PLY (the source)", source, "INRIA 3DGS training", "read: ours; splat-transform, gsplat.js, GaussianSplats3D"),
        ("PLY", os.path.join(ours, "src.ply"), "atex convert", "read: ours (round trip, bit-exact)"),
        (".atex (f32, shuffle-zstd)", os.path.join(ours, "src.atex"), "atex convert", "read: ours"),
        ("SPZ v4", os.path.join(ours, "src.spz"), "atex convert", "read: ours; @adobe/spz (converter_spz_node_test)"),
        ("SPZ v4", os.path.join(work, "st.spz"), "splat-transform", "read: ours"),
        ("glTF KHR_gaussian_splatting", os.path.join(ours, "src.glb"), "atex export",
         "read: ours; Babylon.js, glTF-Validator (tests/web)"),
    ]
    rows.append(("glTF + KHR_gaussian_splatting_compression_spz_2", os.path.join(ours, "src_spz.glb"),
                 "atex export --spz", "read: ours (converter_gltf_test); glTF-Validator (tests/web)"))
    if meshopt:
        rows.append(("glTF + EXT_meshopt_compression (12-bit)", os.path.join(ours, "src_meshopt.glb"), "atex export --meshopt",
                     "read: ours; Babylon.js, glTF-Validator (tests/web)"))
    rows += [
        ("glTF KHR_gaussian_splatting", os.path.join(work, "st.glb"), "splat-transform", "read: ours"),
        ("PlayCanvas compressed PLY", os.path.join(work, "src.compressed.ply"), "splat-transform",
         "read: ours = splat-transform's decoding (converter_websplat_real_test)"),
        ("PlayCanvas SOG (.sog bundle)", os.path.join(work, "src.sog"), "splat-transform",
         "read: ours = splat-transform's decoding (converter_websplat_real_test)"),
        (".splat (antimatter15)", os.path.join(work, "src.splat"), "gsplat.js",
         "read: ours = splat-transform's decoding (converter_websplat_real_test)"),
    ]
    for level in range(3):
        rows.append((f".ksplat level {level}", os.path.join(work, f"src.l{level}.ksplat"), "GaussianSplats3D",
                     "read: ours = splat-transform's decoding (converter_websplat_real_test)"))

    table = []
    for fmt, path, writer, checked in rows:
        size = os.path.getsize(path)
        ok, back = read_back(args.atex, path, work)
        table.append({"format": fmt, "file": os.path.basename(path), "written_by": writer, "checked_by": checked,
                      "bytes": size, "bytes_per_gaussian": size / n, "our_reader": back if ok else f"failed: {back}"})
    when = datetime.date.today().isoformat()
    print(f"Model: {os.path.relpath(source, ROOT)} ({n} Gaussians, SH degree 3); {platform.node()}, {when}")
    print()
    print("| format | written by | checked by | bytes | bytes/Gaussian | our reader |")
    print("|---|---|---|---:|---:|---|")
    for r in table:
        back = r["our_reader"]
        back = f"{back} Gaussians" if isinstance(back, int) else back
        print(f"| {r['format']} | {r['written_by']} | {r['checked_by']} | {r['bytes']:,} | {r['bytes_per_gaussian']:.2f} | {back} |")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"source": source, "gaussians": n, "date": when, "rows": table}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
