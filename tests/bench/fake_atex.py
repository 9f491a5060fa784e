#!/usr/bin/env python3
"""A stand-in for the `atex` binary in the tests of bench/run_matrix.py: it answers train,
eval, info, fps and fit with canned JSON shaped like the real commands' --json output.

Model files are small JSON documents ({"textures": MODE, "gaussians": N}) padded to a size
that depends on the method, so that budgets and model sizes behave plausibly.
Environment (all optional):
  FAKE_ATEX_LOG    append every invocation here (one JSON array of arguments per line)
  FAKE_ATEX_FAIL   regex over the joined arguments: matching calls fail (exit 1, message on stderr)
  FAKE_ATEX_NAN    regex: matching eval calls report a null (NaN) PSNR
  FAKE_ATEX_SLEEP  "REGEX:SECONDS": matching calls sleep first (after writing a checkpoint for train)
  FAKE_ATEX_EVENTS append a JSON object per line when a call starts ({"phase": "start", "pid", "time"
                   (time.time()), "args", "gpu": $CUDA_VISIBLE_DEVICES, "omp": $OMP_NUM_THREADS,
                   "init_exists": whether train's --init file exists}) and when it returns
                   ({"phase": "end", "pid", "time", "rc"}); a killed call has no end event
"""
import json
import os
import re
import sys
import time


def opt(args, name, default=None):
    return args[args.index(name) + 1] if name in args else default


def write_model(path, textures, gaussians, size):
    text = json.dumps({"textures": textures, "gaussians": gaussians})
    with open(path, "w") as f:
        f.write(text + " " * max(0, size - len(text)))


def read_model(path):
    with open(path) as f:
        return json.loads(f.read())


def event(**fields):
    """One line per write (O_APPEND): concurrent fakes, even of two harness processes, share the file."""
    if os.environ.get("FAKE_ATEX_EVENTS"):
        with open(os.environ["FAKE_ATEX_EVENTS"], "a") as f:
            f.write(json.dumps(dict(fields, pid=os.getpid(), time=time.time())) + "\n")


def main():
    args = sys.argv[1:]
    if os.environ.get("FAKE_ATEX_LOG"):
        with open(os.environ["FAKE_ATEX_LOG"], "a") as f:
            f.write(json.dumps(args) + "\n")
    init = opt(args, "--init")
    event(phase="start", args=args, gpu=os.environ.get("CUDA_VISIBLE_DEVICES"), omp=os.environ.get("OMP_NUM_THREADS"),
          init_exists=None if init is None else os.path.exists(init))
    rc = answer(args)
    event(phase="end", rc=rc)
    return rc


def answer(args):
    joined = " ".join(args)
    if os.environ.get("FAKE_ATEX_FAIL") and re.search(os.environ["FAKE_ATEX_FAIL"], joined):
        print("atex %s: E15 numerical-error: injected failure" % args[0], file=sys.stderr)
        return 1
    sleep = os.environ.get("FAKE_ATEX_SLEEP")
    if sleep:
        rx, seconds = sleep.rsplit(":", 1)
        if re.search(rx, joined):
            ckpt = opt(args, "--checkpoint-dir")
            if ckpt:
                os.makedirs(ckpt, exist_ok=True)
                with open(os.path.join(ckpt, "trainer.json"), "w") as f:
                    f.write('{"phase": "fine", "step": 1000}')
            time.sleep(float(seconds))
    cmd = args[0]
    if cmd == "train":
        textures = "none" if opt(args, "--stage") == "1" else opt(args, "--textures", "adaptive")
        size = {"none": 4000, "uniform": 12000, "adaptive": 8000}[textures]
        write_model(opt(args, "--out"), textures, 100, size)
        s1 = opt(args, "--stage") == "1"
        print(json.dumps({"gaussians": 100, "seconds": {"coarse": 10.0 if s1 else 0, "fine": 50.0 if s1 else 0,
                                                         "textures": 0 if s1 else 20.0},
                          "steps": {}, "events": ["resumed from x"] if "--resume" in args else [],
                          "stopped_by_time_limit": False, "peak_memory_bytes": 1 << 30 if s1 else 3 << 29,
                          "backend": "fake"}, indent=2))
        return 0
    if cmd == "fit":
        src, out = args[1], args[2]
        model = read_model(src)
        if "--budget" in args:
            size = int(float(opt(args, "--budget")))
            n = max(1, int(model["gaussians"] * size / os.path.getsize(src)))
        else:
            n = max(1, int(model["gaussians"] * float(opt(args, "--keep-count"))))
            size = int(os.path.getsize(src) * n / model["gaussians"])
        write_model(out, model["textures"], n, size)
        print(json.dumps({"gaussians": n, "bytes": size, "seconds": 1.5}))
        return 0
    if cmd == "eval":
        model = read_model(args[1])
        base = {"none": 25.0, "uniform": 26.0, "adaptive": 26.2}[model["textures"]] - 2.0 * (1 - model["gaussians"] / 100)
        if "--split" in args and args[args.index("--split") + 1] == "train":
            base += 1.5  # training views fit better than held-out ones
        nan = os.environ.get("FAKE_ATEX_NAN") and re.search(os.environ["FAKE_ATEX_NAN"], joined)
        views = []
        for cam in (0, 10):
            for t in range(3):
                p = None if nan else base + 0.1 * cam / 10 + 0.05 * t + (0.03 if model["textures"] == "adaptive" and t == 1 else 0)
                views.append({"camera": cam, "timestep": t, "psnr": p, "ssim": 0.9, "dssim1": 0.05, "dssim2": 0.025,
                              "l1": 0.02, "dynamic_psnr": None if nan else p - 4.0})
        cams = [{"camera": c, "views": 3, "psnr": None if nan else sum(v["psnr"] for v in views if v["camera"] == c) / 3,
                 "ssim": 0.9, "dssim1": 0.05, "dssim2": 0.025, "l1": 0.02,
                 "dynamic_psnr": None if nan else sum(v["psnr"] for v in views if v["camera"] == c) / 3 - 4.0,
                 "dynamic_fraction": 0.1} for c in (0, 10)]
        mean = None if nan else sum(v["psnr"] for v in views) / len(views)
        print(json.dumps({"mean": {"psnr": mean, "ssim": 0.9, "dssim1": 0.05, "dssim2": 0.025, "l1": 0.02,
                                   "dynamic_psnr": None if nan else mean - 4.0, "dynamic_views": len(views)},
                          "cameras": cams, "views": views, "backend": "fake"}, indent=2))
        return 0
    if cmd == "info":
        model = read_model(args[1])
        n = model["gaussians"]
        t = {"mode": model["textures"], "present": model["textures"] != "none"}
        if t["present"]:
            hist = {k: 0 for k in ("1x1", "1x2", "1x4", "2x1", "2x2", "2x4", "4x1", "4x2", "4x4")}
            if model["textures"] == "uniform":
                hist["4x4"] = n
            else:
                hist["1x1"], hist["2x2"], hist["4x4"] = n - n // 2, n // 4, n // 2 - n // 4
            texels = sum(c * int(k[0]) * int(k[2]) for k, c in hist.items())
            t.update(histogram_hxw=hist, texels=texels, uniform_4x4_texels=16 * n, texel_bytes=texels * 16,
                     uniform_4x4_texel_bytes=256 * n, stored_bytes=texels * 16 + 64)
        print(json.dumps({"file": args[1], "file_size": os.path.getsize(args[1]), "gaussians": n, "textures": t,
                          "components": [{"component": "gaussians", "bytes": 4000, "bytes_per_gaussian": 40.0}]}))
        return 0
    if cmd == "fps":
        size = opt(args, "--size", "640x360")
        w, h = (int(x) for x in size.split("x"))
        print(json.dumps({"width": w, "height": h, "fps": 1e8 / (w * h), "median_ms": w * h / 1e5,
                          "method": "fake", "backend": "fake"}))
        return 0
    print("fake atex: unknown command %s" % cmd, file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
