#!/usr/bin/env python3
"""Runs bench/charts.py on a committed example CSV and checks that every chart is a complete,
valid PNG (signature, IHDR, CRC of every chunk, IEND) of a plausible size.

    python3 tests/bench/test_charts.py --csv bench/testdata/example_results.csv --out DIR
Exit status 77 (CTest SKIP_RETURN_CODE) when this interpreter has no matplotlib.
"""
import argparse
import csv
import os
import shutil
import struct
import subprocess
import sys
import zlib

SOURCE = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
EXPECTED = ["psnr_vs_model_mib.png", "psnr_vs_fps.png", "psnr_vs_train_time.png", "texel_histogram.png"]


def check_png(path):
    """(width, height) of a PNG whose every chunk CRC is right and that ends with IEND."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("%s: no PNG signature" % path)
    at, chunks, size = 8, [], None
    while at < len(data):
        if at + 8 > len(data):
            raise ValueError("%s: truncated chunk header at byte %d" % (path, at))
        length, kind = struct.unpack(">I4s", data[at:at + 8])
        body = data[at + 8:at + 8 + length]
        if len(body) != length or at + 12 + length > len(data):
            raise ValueError("%s: truncated %s chunk" % (path, kind))
        crc, = struct.unpack(">I", data[at + 8 + length:at + 12 + length])
        if zlib.crc32(kind + body) & 0xFFFFFFFF != crc:
            raise ValueError("%s: bad CRC in %s chunk" % (path, kind))
        if kind == b"IHDR":
            size = struct.unpack(">II", body[:8])
        chunks.append(kind)
        at += 12 + length
        if kind == b"IEND":
            break
    if not chunks or chunks[0] != b"IHDR" or chunks[-1] != b"IEND" or b"IDAT" not in chunks:
        raise ValueError("%s: chunk order %s" % (path, chunks))
    if at != len(data):
        raise ValueError("%s: %d bytes after IEND" % (path, len(data) - at))
    return size


def check_selection(args):
    """--budgets, --charts and --mean-seeds: what they keep, and their usage errors. Returns failures."""
    failures = 0
    sys.path.insert(0, os.path.dirname(os.path.abspath(args.charts)))
    import charts  # noqa: E402 (the module under test, from the path given)
    rows = [{"dataset": "d", "variant": "full", "method": "uniform", "budget": b, "seed": s, "psnr": str(p),
             "dynamic_psnr": str(p - 4), "model_mib": str(m)}
            for b, s, p, m in (("b25", "1", 20.0, 10.0), ("b25", "2", 22.0, 12.0), ("b50", "1", 23.0, 20.0))]
    mean = charts.mean_over_seeds(rows)
    got = [(r["budget"], float(r["psnr"]), float(r["dynamic_psnr"]), float(r["model_mib"])) for r in mean]
    if got != [("b25", 21.0, 17.0, 11.0)]:
        print("FAIL: mean_over_seeds kept %s (expected b25 only, the cell both seeds have, at 21 dB, dynamic "
              "17 dB, 11 MiB)" % got)
        failures += 1
    failures += check_dynamic_metric(args)
    folder = os.path.join(args.out, "selection")
    shutil.rmtree(folder, ignore_errors=True)
    picked = subprocess.run([sys.executable, args.charts, args.csv, "--out", folder, "--budgets", "^(full|b25)$",
                             "--charts", "size", "--mean-seeds"], capture_output=True, text=True)
    written = sorted(os.listdir(folder)) if os.path.isdir(folder) else []
    if picked.returncode != 0 or written != [EXPECTED[0]]:
        print("FAIL: --charts size wrote %s (exit %d: %s)" % (written, picked.returncode, picked.stderr))
        failures += 1
    for bad in (["--charts", "sizes"], ["--budgets", "("], ["--budgets", "^nothing$"],
                ["--seed", "6666", "--mean-seeds"], ["--mean-seeds", "--charts", "size,fps"]):
        proc = subprocess.run([sys.executable, args.charts, args.csv, "--out", folder] + bad,
                              capture_output=True, text=True)
        if proc.returncode != 2 or not proc.stderr.startswith("charts:"):
            print("FAIL: %s exited with %d: %s" % (" ".join(bad), proc.returncode, proc.stderr))
            failures += 1
    return failures


def check_dynamic_metric(args):
    """--metric dynamic_psnr draws the dynamic region's PSNR (rows given one: psnr - 3) into
    dynamic_psnr_vs_*.png and leaves the psnr charts alone. Returns failures."""
    folder = os.path.join(args.out, "dynamic")
    shutil.rmtree(folder, ignore_errors=True)
    os.makedirs(folder)
    with open(args.csv, newline="") as f:
        reader = csv.DictReader(f)
        fields = list(reader.fieldnames) + (["dynamic_psnr"] if "dynamic_psnr" not in reader.fieldnames else [])
        rows = list(reader)
    for r in rows:
        try:
            r["dynamic_psnr"] = repr(float(r["psnr"]) - 3.0)
        except ValueError:
            r["dynamic_psnr"] = ""
    dynamic_csv = os.path.join(folder, "results.csv")
    with open(dynamic_csv, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        w.writerows(rows)
    proc = subprocess.run([sys.executable, args.charts, dynamic_csv, "--out", folder, "--metric", "dynamic_psnr",
                           "--charts", "size,fps,time"], capture_output=True, text=True)
    written = sorted(n for n in os.listdir(folder) if n.endswith(".png"))
    expected = sorted(n.replace("psnr_vs", "dynamic_psnr_vs") for n in EXPECTED[:3])
    if proc.returncode != 0 or written != expected:
        print("FAIL: --metric dynamic_psnr wrote %s, expected %s (exit %d: %s)"
              % (written, expected, proc.returncode, proc.stderr))
        return 1
    bad = subprocess.run([sys.executable, args.charts, dynamic_csv, "--out", folder, "--metric", "lpips"],
                         capture_output=True, text=True)
    if bad.returncode != 2:
        print("FAIL: --metric lpips exited with %d" % bad.returncode)
        return 1
    return 0


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--csv", default=os.path.join(SOURCE, "bench", "testdata", "example_results.csv"))
    p.add_argument("--charts", default=os.path.join(SOURCE, "bench", "charts.py"))
    p.add_argument("--out", required=True)
    args = p.parse_args()
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        print("SKIP: matplotlib is not installed for %s (Debian: python3-matplotlib, /usr/bin/python3)" % sys.executable)
        return 77
    for name in EXPECTED:
        try:
            os.remove(os.path.join(args.out, name))
        except OSError:
            pass
    proc = subprocess.run([sys.executable, args.charts, args.csv, "--out", args.out, "--title", "test"],
                          capture_output=True, text=True)
    print(proc.stdout + proc.stderr)
    if proc.returncode != 0:
        print("FAIL: charts.py exited with %d" % proc.returncode)
        return 1
    failures = 0
    # --seed keeps one seed's rows; a seed without rows is an error, not empty charts.
    absent = subprocess.run([sys.executable, args.charts, args.csv, "--out", args.out, "--seed", "12345"],
                            capture_output=True, text=True)
    if absent.returncode != 2 or "seed 12345" not in absent.stderr:
        print("FAIL: --seed 12345 (no such rows) exited with %d: %s" % (absent.returncode, absent.stderr))
        failures += 1
    # A seed that has rows draws them (into a folder of its own, so the checks below see the full run).
    with open(args.csv) as f:
        seed = next(csv.DictReader(f))["seed"]
    one_seed = subprocess.run([sys.executable, args.charts, args.csv, "--out", os.path.join(args.out, "one_seed"),
                               "--seed", seed], capture_output=True, text=True)
    if one_seed.returncode != 0 or not os.path.exists(os.path.join(args.out, "one_seed", EXPECTED[0])):
        print("FAIL: --seed %s exited with %d: %s" % (seed, one_seed.returncode, one_seed.stderr))
        failures += 1
    failures += check_selection(args)
    for name in EXPECTED:
        path = os.path.join(args.out, name)
        try:
            w, h = check_png(path)
            size = os.path.getsize(path)
            if w < 300 or h < 200 or size < 10000:
                raise ValueError("%s: %dx%d, %d bytes: too small to hold a chart" % (path, w, h, size))
            print("ok   %s: %dx%d, %d bytes" % (path, w, h, size))
        except (OSError, ValueError) as e:
            print("FAIL %s" % e)
            failures += 1
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
