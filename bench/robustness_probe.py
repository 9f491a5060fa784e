#!/usr/bin/python3
"""Robustness probe (issue 24): runs classes of hostile or out-of-contract inputs through the
built `atex` binary and counts, per class, the outcomes of the issue's table:

    input class | tries | clean errors | accepted (valid) | crashes | hangs | exit-0 wrong

Each case states what a correct binary does: "refuse" (a non-zero exit with a message, no
signal) or "accept" (exit 0). A refusal-expected case that exits 0 is "exit-0 wrong"; an
accept-expected case that fails is counted in "clean errors" and listed as unexpected. A
signal, an exit >= 128 or a sanitizer report is a crash; running past --timeout is a hang.
Corrupted-file classes mutate real files (seeded, reproducible) and accept either outcome
unless the process crashes or hangs.

    /usr/bin/python3 bench/robustness_probe.py --atex build/bin/atex [--data ../shared/data]
        [--mutations 200] [--seed 24] [--out bench/results/robustness_probe_cpu]

Writes OUT.md (the table and the unexpected cases) and OUT.json (every case), and prints the
table. Exit status 1 when any class has a crash, a hang or an exit-0 wrong result.
"""
import argparse
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TINY = ["--backend", "cpu", "--set", "stage1.coarse_iterations=1", "--set", "stage1.fine_iterations=1",
        "--set", "stage1.init_points=300", "--set", "stage2.iterations=2", "--set", "stage2.growth_steps=[1]",
        "--set", "eval_every=0", "--set", "stage2.batch_size=1", "--set", "checkpoint_every=0"]


class Probe:
    def __init__(self, atex, work, timeout):
        self.atex, self.work, self.timeout = atex, work, timeout
        self.cases = []

    def path(self, name):
        return os.path.join(self.work, name)

    def run(self, klass, args, expect, check=None, note=""):
        """Runs `atex args`; `expect` is "refuse", "accept" or "either"; `check(proc)` may
        return a reason why an exit-0 result is wrong."""
        start = time.time()
        try:
            proc = subprocess.run([self.atex] + args, capture_output=True, text=True, errors="replace",
                                  timeout=self.timeout, cwd=self.work)
            seconds = time.time() - start
            code = proc.returncode
            sanitizer = "ERROR: AddressSanitizer" in proc.stderr or "runtime error:" in proc.stderr
            if code < 0 or code >= 128 or sanitizer:
                outcome = "crash"
            elif code == 0:
                wrong = check(proc) if check else None
                outcome = "exit0_wrong" if expect == "refuse" or wrong else "accepted"
                note = note or (wrong or "")
            else:
                outcome = "clean_error" if proc.stderr.strip() else "exit0_wrong"  # an error must say why
                if expect == "accept":
                    note = note or "expected success: " + proc.stderr.strip().splitlines()[-1][:200]
            detail = proc.stderr.strip().splitlines()[-1][:200] if proc.stderr.strip() else ""
        except subprocess.TimeoutExpired:
            seconds, code, outcome, detail = time.time() - start, None, "hang", ""
        self.cases.append({"class": klass, "args": args, "expect": expect, "outcome": outcome, "exit": code,
                           "seconds": round(seconds, 3), "message": detail, "note": note})
        return outcome


def cli_values(p, asset, npz):
    data = ["--data", npz]
    camera = ["--size", "32x32", "--intrinsics", "30", "30", "16", "16", "--world-to-camera"] + \
        "1 0 0 0 0 1 0 0 0 0 1 4 0 0 0 1".split()
    k = "CLI values"
    for v in ["0", "-1", "nan", "1abc", "", "1e3", "0x10", "99999999999999999999"]:
        p.run(k, ["fps", asset] + data + ["--backend", "cpu", "--repeats", v], "refuse")
    p.run(k, ["fps", asset] + data + ["--backend", "cpu", "--repeats", "1"], "accept")
    for v in ["nan", "inf", "-inf", "1e999", "0.5x", ""]:
        p.run(k, ["render", asset, "-o", p.path("t.png")] + camera + ["--time", v], "refuse")
    for v in ["4294967344x48", "0x0", "10", "abcxdef", "-5x5", "65537x10"]:
        p.run(k, ["render", asset, "-o", p.path("s.png"), "--size", v, "--intrinsics", "30", "30", "16", "16",
                  "--world-to-camera"] + "1 0 0 0 0 1 0 0 0 0 1 4 0 0 0 1".split(), "refuse")
    for v in ["test:1abc", "test:-1", "val:0", "test:99999", "test:", "1"]:
        p.run(k, ["render", asset, "-o", p.path("v.png"), "--view", v] + data, "refuse")
    p.run(k, ["render", asset, "-o", p.path("v.png"), "--view", "test:1", "--size", "32x32"] + data, "refuse",
          note="--size with --data")
    p.run(k, ["render", asset, "-o", p.path("ok.png"), "--view", "test:1", "--backend", "cpu"] + data, "accept")
    for v in [".", "0", "-5MB", "1.2.3MB", "100KiB,102400", "nan", "1e3", "5XB", "1MiB,"]:
        p.run(k, ["fit", asset, p.path("b_{}.atex"), "--budget", v], "refuse")
    for v in ["nan", "inf", "0", "1.5", "-0.1", "half"]:
        p.run(k, ["fit", asset, p.path("k.atex"), "--keep-count", v], "refuse")
    p.run(k, ["fit", asset, p.path("p.atex"), "--keep-count", "0.5", "--probes", "0"], "refuse")
    p.run(k, ["fit", asset, p.path("kc.atex"), "--keep-count", "0.5"], "accept")
    for opt, v in [("--seed", "-1"), ("--checkpoint-every", "x"), ("--time-limit", "nan"), ("--downscale", "0"),
                   ("--timesteps", "-1"), ("--test-cameras", "a,b"), ("--train-cameras", "1.5")]:
        p.run(k, ["train"] + data + ["--out", p.path("o.atex"), opt, v], "refuse")
    p.run(k, ["eval", asset] + data + ["--near-plane", "nan"], "refuse")
    p.run(k, ["convert", asset, p.path("c.ply"), "--time", "nan"], "refuse")
    p.run(k, ["export", asset, p.path("e.glb"), "--time", "inf"], "refuse")


def config_checks(p, npz):
    k = "training config"
    bad = ["stage2.time_bins=0", "stage2.time_bins=-1", "stage2.time_bins=1e8", "stage1.densify.interval=0",
           "stage1.densify.interval=-1", "background=[2,2,2]", "background=[1,1,1,1]", "background=[1,1]",
           "stage1.batch_size=1.5", "stage1.batch_size=true", "stage1.batch_size=0", "stage1.lr.opacity=-1",
           "stage1.lr.position.initial=-1", "stage1.lr.grid.final=0", "stage1.lambda_dssim=5", "stage1.sh_degree=7",
           "near_plane=0", "near_plane=-1", "stage1.deformation.grid.channels=0", "stage1.deformation.grid.multires=[]",
           "stage2.texel_budget_fraction=0.01", "stage2.iterations=2 --set stage2.growth_steps=[10]",
           "stage1.densify.max_gaussians=-1", "stage1.init_method=magic", "seed=-1", "stage2.anisotropy_ratio=0.5",
           "stage1.unknown_key=1", "stage1.coarse_iterations=4294967297"]
    for assignment in bad:
        sets = []
        for piece in assignment.split(" --set "):
            sets += ["--set", piece]
        p.run(k, ["train", "--data", npz, "--out", p.path("cfg.atex")] + TINY + sets, "refuse")
    ok = ["background=[1,1,1]", "stage1.lambda_dssim=0", "stage2.textures=\"uniform\""]
    for i, assignment in enumerate(ok):
        out = p.path("cfg_ok%d.atex" % i)

        def exists(proc, out=out):
            return None if os.path.exists(out) else "exit 0 without the output"
        p.run(k, ["train", "--data", npz, "--out", out] + TINY + ["--set", assignment], "accept", check=exists)


def resume_checks(p, npz):
    k = "resume"
    ckpt = p.path("ckpt")
    first = p.run(k, ["train", "--data", npz, "--out", p.path("r0.atex")] + TINY[:-2] +
                  ["--set", "stage2.iterations=6", "--checkpoint-dir", ckpt, "--checkpoint-every", "1"], "accept")
    if first != "accepted":
        return
    p.run(k, ["train", "--data", npz, "--backend", "cpu", "--resume", ckpt, "--out", p.path("r1.atex"), "--set",
              "stage1.deformation.grid.channels=8"], "refuse")
    p.run(k, ["train", "--data", npz, "--backend", "cpu", "--resume", ckpt, "--out", p.path("r2.atex"),
              "--train-cameras", "10"], "refuse")
    p.run(k, ["train", "--data", npz, "--backend", "cpu", "--resume", ckpt, "--out", p.path("r3.atex"), "--set",
              "background=[1,1,1]"], "refuse")

    def honours(proc):
        steps = json.loads(proc.stdout)["steps"]["textures"]
        return None if steps <= 6 else "resumed into %d stage-2 steps, not the checkpoint's 6" % steps
    p.run(k, ["train", "--data", npz, "--backend", "cpu", "--resume", ckpt, "--json", "--out", p.path("r4.atex")],
          "accept", check=honours)


def outputs(p, asset):
    k = "outputs"
    src = p.path("m.atex")
    shutil.copy(asset, src)
    with open(p.path("existing.atex"), "w") as f:
        f.write("precious")

    def untouched(path, text):
        return lambda proc: None if open(path).read() == text else "clobbered " + path
    p.run(k, ["pack", src, p.path("existing.atex")], "refuse")
    p.run(k, ["pack", src, src], "refuse")
    p.run(k, ["pack", src, p.path("out.ply")], "refuse")
    p.run(k, ["convert", src, p.path("out2.ply"), "--to", "atex"], "refuse")
    p.run(k, ["fit", src, src, "--keep-count", "0.5"], "refuse")
    p.run(k, ["fit", src, p.path("existing.atex"), "--keep-count", "0.5"], "refuse")
    shutil.copy(asset, p.path("m.bin"))
    p.run(k, ["export", p.path("m.bin"), p.path("m.gltf"), "--force"], "refuse")
    p.run(k, ["export", src, p.path("g.gltf")], "accept")
    p.run(k, ["import", p.path("g.gltf"), p.path("g.bin"), "--force"], "refuse")
    p.run(k, ["export", src, p.path("s.glb")], "accept")
    p.run(k, ["import", p.path("s.glb"), p.path("s.glb")], "refuse")
    p.run(k, ["export", src, p.path("s.glb")], "refuse")
    p.run(k, ["convert", src, p.path("existing.atex")], "refuse")
    p.run(k, ["pack", src, p.path("existing.atex"), "--force"], "accept")
    p.run(k, ["pack", src, src, "--force"], "accept")


def json_errors(p, asset):
    k = "--json errors"

    def is_json_error(proc):
        return None

    for args in (["info", "--json", p.path("missing.atex")], ["verify", "--json", p.path("missing.atex")],
                 ["fit", "--json", asset, p.path("j.atex"), "--budget", "."],
                 ["pack", "--json", asset, asset], ["export", "--json", asset, p.path("x.txt")]):
        outcome = p.run(k, args, "refuse")
        case = p.cases[-1]
        try:
            doc = json.loads(subprocess.run([p.atex] + args, capture_output=True, text=True, timeout=p.timeout,
                                            cwd=p.work).stdout)
            ok = "error" in doc and all(key in doc["error"] for key in ("code", "name", "message", "path", "offset"))
        except (ValueError, subprocess.TimeoutExpired):
            ok = False
        if outcome == "clean_error" and not ok:
            case["outcome"], case["note"] = "exit0_wrong", "stdout is not a JSON error"


def mutate(data, rng):
    data = bytearray(data)
    kind = rng.choice(["flip", "truncate", "splice", "zero"])
    if kind == "flip":
        for _ in range(rng.randint(1, 8)):
            i = rng.randrange(len(data))
            data[i] ^= 1 << rng.randrange(8)
    elif kind == "truncate":
        data = data[:rng.randrange(len(data))]
    elif kind == "splice":
        i, j = sorted(rng.randrange(len(data)) for _ in range(2))
        data[i:i] = data[i:j][:4096]
    else:
        i = rng.randrange(len(data))
        data[i:i + rng.randint(1, 64)] = bytes(min(64, len(data) - i))
    return bytes(data)


def corrupted(p, asset, ply, spz, count, rng):
    sources = [("corrupted .atex (verify)", asset, ".atex", lambda f: ["verify", f]),
               ("corrupted .atex (info --json)", asset, ".atex", lambda f: ["info", "--json", f])]
    if ply:
        sources.append(("corrupted PLY (convert)", ply, ".ply", lambda f: ["convert", f, p.path("o%d.atex" % rng.randrange(1 << 30))]))
    if spz:
        sources.append(("corrupted SPZ (convert)", spz, ".spz", lambda f: ["convert", f, p.path("o%d.atex" % rng.randrange(1 << 30))]))
    for klass, source, ext, command in sources:
        original = open(source, "rb").read()
        for i in range(count):
            path = p.path("mut%d%s" % (i, ext))
            with open(path, "wb") as f:
                f.write(mutate(original, rng))
            p.run(klass, command(path), "either")
            os.remove(path)
        for f in os.listdir(p.work):
            if f.startswith("o") and f.endswith(".atex"):
                os.remove(p.path(f))


def table(cases):
    order, rows = [], {}
    for c in cases:
        if c["class"] not in rows:
            order.append(c["class"])
            rows[c["class"]] = dict(tries=0, clean_error=0, accepted=0, crash=0, hang=0, exit0_wrong=0)
        r = rows[c["class"]]
        r["tries"] += 1
        r[c["outcome"]] += 1
    lines = ["| input class | tries | clean errors | accepted (valid) | crashes | hangs | exit-0 wrong |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    total = dict(tries=0, clean_error=0, accepted=0, crash=0, hang=0, exit0_wrong=0)
    for name in order:
        r = rows[name]
        for key in total:
            total[key] += r[key]
        lines.append("| %s | %d | %d | %d | %d | %d | %d |" % (name, r["tries"], r["clean_error"], r["accepted"],
                                                                r["crash"], r["hang"], r["exit0_wrong"]))
    lines.append("| **all** | %d | %d | %d | %d | %d | %d |" % (total["tries"], total["clean_error"], total["accepted"],
                                                                 total["crash"], total["hang"], total["exit0_wrong"]))
    return "\n".join(lines), rows, total


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--atex", default=os.path.join(ROOT, "build/bin/atex"))
    ap.add_argument("--data", default=os.environ.get("ATEX_DATA_DIR", os.path.join(ROOT, "../shared/data")))
    ap.add_argument("--mutations", type=int, default=200, help="corrupted files per class")
    ap.add_argument("--seed", type=int, default=24)
    ap.add_argument("--timeout", type=float, default=120.0, help="seconds before a case counts as a hang")
    ap.add_argument("--out", default=None, help="write OUT.md and OUT.json")
    ap.add_argument("--classes", default="cli,config,resume,outputs,json,corrupted")
    ap.add_argument("--table-from", default=None, help="re-render the table of an earlier OUT.json (no runs)")
    args = ap.parse_args()
    if args.table_from:
        doc = json.load(open(args.table_from))
        write_report(doc["cases"], doc["seconds"], args)
        return 0
    atex = os.path.abspath(args.atex)
    asset = os.path.join(ROOT, "samples/sample.atex")
    npz = os.path.join(args.data, "dnerf_lego_tiny/tiny_dnerf_data.npz")
    ply = os.path.join(args.data, "splats/kacytran1122_try_iter7000_point_cloud.ply")
    spz = None
    splats = os.path.join(args.data, "splats")
    if os.path.isdir(splats):
        spz = next((os.path.join(splats, f) for f in sorted(os.listdir(splats)) if f.endswith(".spz")), None)
    for path in (atex, npz):
        if not os.path.exists(path):
            sys.exit("robustness_probe.py: %s is missing" % path)
    rng = random.Random(args.seed)
    classes = set(args.classes.split(","))
    with tempfile.TemporaryDirectory(prefix="atex-probe-") as work:
        p = Probe(atex, work, args.timeout)
        started = time.time()
        if "cli" in classes:
            cli_values(p, asset, npz)
        if "config" in classes:
            config_checks(p, npz)
        if "resume" in classes:
            resume_checks(p, npz)
        if "outputs" in classes:
            outputs(p, asset)
        if "json" in classes:
            json_errors(p, asset)
        if "corrupted" in classes:
            corrupted(p, asset, ply if os.path.exists(ply) else None, spz, args.mutations, rng)
        seconds = time.time() - started
    text, rows, total = table(p.cases)
    write_report(p.cases, seconds, args)
    _, _, total = table(p.cases)
    return 1 if total["crash"] or total["hang"] or total["exit0_wrong"] else 0


def write_report(cases, seconds, args):
    text, rows, total = table(cases)
    # Listed: every wrong outcome, and accept-expected cases that failed.
    unexpected = [c for c in cases if c["outcome"] in ("crash", "hang", "exit0_wrong") or
                  c["note"].startswith("expected success")]
    header = "Command: `/usr/bin/python3 bench/robustness_probe.py --mutations %d --seed %d`; %.0f s; %s" % (
        args.mutations, args.seed, seconds, time.strftime("%Y-%m-%d", time.gmtime()))
    print(text)
    print(header)
    for c in unexpected:
        print("unexpected: [%s] atex %s -> %s %s" % (c["class"], " ".join(c["args"]), c["outcome"], c["note"]))
    if args.out:
        os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
        with open(args.out + ".md", "w") as f:
            f.write(text + "\n\n" + header + "\n")
            for c in unexpected:
                f.write("\n- unexpected: [%s] `atex %s` -> %s %s" % (c["class"], " ".join(c["args"]), c["outcome"],
                                                                    c["note"]))
            f.write("\n")
        if not args.table_from:
            with open(args.out + ".json", "w") as f:
                json.dump({"rows": rows, "total": total, "seconds": seconds, "cases": cases}, f, indent=1)


if __name__ == "__main__":
    sys.exit(main())
