#!/usr/bin/env python3
"""Run an experiment matrix of `atex` commands from a JSON config (issue 9).

    python3 bench/run_matrix.py CONFIG.json [--atex PATH] [--out DIR] [--dry-run] [--list]
                                [--only REGEX] [--time-limit S] [--stage1-time-limit S] [--stage2-time-limit S]
                                [--deadline S] [--retry-failed] [--skip-fps]

Python 3 standard library only (the GPU machine has no matplotlib); run it from the
repository root (relative dataset paths are resolved against the working directory).

A cell is dataset x variant x seed x method x budget. For each cell the harness
  1. trains stage 1 once per (dataset, variant, seed) and caches it (models/.../stage1.atex),
  2. trains stage 2 from that same stage-1 model, once per method (models/.../<method>.atex;
     method "none" has no stage 2: the stage-1 model is the 4DGS row),
  3. optionally fits the model to a budget (`atex fit IN OUT --budget BYTES` or
     `--keep-count F --order-from STAGE1.atex`),
  4. evaluates it (`atex eval --json`: per-view, per-camera and mean PSNR/SSIM/DSSIM1/DSSIM2),
     inspects it (`atex info --json`: texture bytes and texel histogram) and times it
     (`atex fps --json` at the dataset resolution and at the configured sizes),
and appends one JSON row to OUT/results.jsonl, then rewrites OUT/results.csv.

Resumable: a cell whose row exists in results.jsonl is skipped (failed rows too, unless
--retry-failed). Cached models are reused; a training run that was interrupted (--deadline,
or the whole process killed) resumes from its checkpoint folder (--checkpoint-dir/--resume).
A failing step (non-zero exit, unreadable JSON, NaN metric, PSNR below the floor, no
Gaussians left) gives a failure row with its cause; the matrix always goes on.

Exit status: 0 the matrix is complete (failure rows included), 3 stopped at --deadline
(rerun the same command to continue), 2 bad config or command line.

Config (JSON; see bench/configs/*.json):
  name            results go to out/<name> (git-ignored) unless --out
  datasets        {NAME: {"path": P, "args": [atex dataset options, e.g. "--timesteps", "30"],
                          "fps_args": [options for `atex fps`; default: --timesteps/--dataset-kind
                                       taken from args]}}
                  P may use ${VAR} or ${VAR:-default} (environment).
  variants        {NAME: {"args": [dataset options for train AND eval, e.g. "--timestep-stride", "4"],
                          "eval_args": [... for eval only; default = args]}}   default {"full": {}}
  seeds           [6666]
  stage1          {"args": [...], "checkpoint_every": 1000, "time_limit": 0}   (atex train --stage 1;
                  time_limit > 0: --time-limit S, the model is written when it stops; --time-limit overrides)
  stage2          {"args": [...], "checkpoint_every": 1000, "time_limit": 0}   (every method's stage 2)
  methods         {NAME: {"stage2": false} | {"textures": "uniform"|"adaptive", "set": ["k=v", ...],
                          "args": [...]}}
  budgets         ["full" | {"name": N, "budget_of": METHOD, "fraction": F}
                           | {"name": N, "budget_mib": MIB}
                           | {"name": N, "keep_count": F, "order_from": "stage1"}]   default ["full"]
  fit             {"args": [...], "pass_data": true, "budget_unit": "bytes" | "mib"}   (pass_data: --data and
                  the dataset's --timesteps/--downscale/--dataset-kind; --backend is always passed)
  fps             {"sizes": ["native", "1352x1014"], "repeats": 100, "view": "test:0"}
  eval            {"args": [...]}
  backend         "auto" | "cuda" | "cpu"          (passed as --backend to train/eval/fps)
  only, skip      regular expressions over cell ids that restrict the cross product
  psnr_floor      cells below this mean test PSNR are failure rows (default 10)
  command_timeout seconds; a command running longer is killed and its cell fails (default: none)
"""

import argparse
import csv
import datetime
import io
import json
import math
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import time

EXIT_COMPLETE = 0
EXIT_USAGE = 2
EXIT_INCOMPLETE = 3
HIST_KEYS = ["%dx%d" % (h, w) for h in (1, 2, 4) for w in (1, 2, 4)]  # h x w
MIB = float(1 << 20)


class ConfigError(Exception):
    pass


class Interrupted(Exception):
    """The --deadline passed while a command ran (the cell gets no row; rerun to continue)."""
    def __init__(self, seconds=0.0):
        super().__init__("deadline reached")
        self.seconds = seconds


class StepFailed(Exception):
    def __init__(self, step, cause):
        super().__init__("%s: %s" % (step, cause))
        self.step = step
        self.cause = cause


# ---------------------------------------------------------------------------------------
# Config

def expand_env(text):
    def repl(m):
        name, default = m.group(1), m.group(3)
        value = os.environ.get(name)
        if value:
            return value
        if default is not None:
            return default
        raise ConfigError("environment variable %s is not set (used in %r)" % (name, text))
    return re.sub(r"\$\{([A-Za-z_][A-Za-z0-9_]*)(:-([^}]*))?\}", repl, text)


def as_list(value, where):
    if value is None:
        return []
    if not isinstance(value, list) or not all(isinstance(v, (str, int, float)) for v in value):
        raise ConfigError("%s must be a list of strings" % where)
    return [str(v) for v in value]


def option_values(args, names):
    """The [name, value] pairs of `args` whose name is in `names` (both '--x v' and '--x=v')."""
    out, i = [], 0
    while i < len(args):
        a = args[i]
        key = a.split("=", 1)[0]
        if key in names:
            if "=" in a:
                out.append(a)
            elif i + 1 < len(args):
                out += [a, args[i + 1]]
                i += 1
        i += 1
    return out


def load_config(path):
    try:
        with open(path) as f:
            cfg = json.load(f)
    except (OSError, ValueError) as e:
        raise ConfigError("%s: %s" % (path, e))
    if not isinstance(cfg, dict):
        raise ConfigError("%s: not a JSON object" % path)
    cfg.setdefault("name", os.path.splitext(os.path.basename(path))[0])
    if not isinstance(cfg.get("datasets"), dict) or not cfg["datasets"]:
        raise ConfigError("%s: 'datasets' must be a non-empty object" % path)
    for name, d in cfg["datasets"].items():
        if not isinstance(d, dict) or not isinstance(d.get("path"), str):
            raise ConfigError("dataset %s: needs a 'path'" % name)
        expand_env(d["path"])  # an unset ${VAR} without a default is a config error now, not mid-run
        d["args"] = as_list(d.get("args"), "dataset %s args" % name)
        if "fps_args" in d:
            d["fps_args"] = as_list(d["fps_args"], "dataset %s fps_args" % name)
        else:
            d["fps_args"] = option_values(d["args"], ("--timesteps", "--dataset-kind"))
    variants = cfg.get("variants") or {"full": {}}
    if not isinstance(variants, dict):
        raise ConfigError("'variants' must be an object")
    for name, v in variants.items():
        v["args"] = as_list(v.get("args"), "variant %s args" % name)
        v["eval_args"] = as_list(v["eval_args"], "variant %s eval_args" % name) if "eval_args" in v else v["args"]
    cfg["variants"] = variants
    seeds = cfg.get("seeds", [6666])
    if not isinstance(seeds, list) or not seeds or not all(isinstance(s, int) and s >= 0 for s in seeds):
        raise ConfigError("'seeds' must be a non-empty list of non-negative integers")
    cfg["seeds"] = seeds
    for stage in ("stage1", "stage2"):
        s = cfg.setdefault(stage, {})
        s["args"] = as_list(s.get("args"), stage + " args")
        s.setdefault("checkpoint_every", 1000)
        s.setdefault("time_limit", 0)
    methods = cfg.get("methods")
    if not isinstance(methods, dict) or not methods:
        raise ConfigError("'methods' must be a non-empty object")
    for name, m in methods.items():
        if not isinstance(m, dict):
            raise ConfigError("method %s: not an object" % name)
        m.setdefault("stage2", name != "none")
        if m["stage2"]:
            m.setdefault("textures", "adaptive")
            if m["textures"] not in ("uniform", "adaptive", "none"):
                raise ConfigError("method %s: textures must be uniform, adaptive or none" % name)
        m["set"] = as_list(m.get("set"), "method %s set" % name)
        m["args"] = as_list(m.get("args"), "method %s args" % name)
    budgets = []
    for b in cfg.get("budgets", ["full"]):
        if b == "full" or b == {"name": "full"}:
            budgets.append({"name": "full", "kind": "full"})
            continue
        if not isinstance(b, dict) or not isinstance(b.get("name"), str):
            raise ConfigError("budget %r: needs a 'name'" % (b,))
        if "keep_count" in b:
            b["kind"] = "keep_count"
            if not 0 < float(b["keep_count"]) <= 1:
                raise ConfigError("budget %s: keep_count must be in (0, 1]" % b["name"])
            b.setdefault("order_from", "stage1")
        elif "budget_mib" in b:
            b["kind"] = "budget"
        elif "budget_of" in b and "fraction" in b:
            b["kind"] = "budget"
            ref = methods.get(b["budget_of"])
            if ref is None:
                raise ConfigError("budget %s: budget_of names no method (%s)" % (b["name"], b["budget_of"]))
        else:
            raise ConfigError("budget %s: needs keep_count, budget_mib, or budget_of + fraction" % b["name"])
        budgets.append(b)
    names = [b["name"] for b in budgets]
    if len(set(names)) != len(names):
        raise ConfigError("budget names must be unique")
    cfg["budgets"] = budgets
    fit = cfg.setdefault("fit", {})
    fit["args"] = as_list(fit.get("args"), "fit args")
    fit.setdefault("pass_data", True)
    if fit.setdefault("budget_unit", "bytes") not in ("bytes", "mib"):
        raise ConfigError("fit.budget_unit must be bytes or mib")
    fps = cfg.setdefault("fps", {})
    fps.setdefault("sizes", ["native", "1352x1014"])
    fps.setdefault("repeats", 100)
    fps.setdefault("view", "test:0")
    for size in fps["sizes"]:
        if size != "native" and not re.fullmatch(r"\d+x\d+", size):
            raise ConfigError("fps size %r: 'native' or WxH" % size)
    ev = cfg.setdefault("eval", {})
    ev["args"] = as_list(ev.get("args"), "eval args")
    cfg.setdefault("backend", "auto")
    cfg.setdefault("psnr_floor", 10.0)
    cfg.setdefault("command_timeout", 0)
    return cfg


def cells(cfg):
    """Every cell of the matrix, in run order (stage-1 models are shared by consecutive cells),
    restricted by the config's "only" / "skip" regular expressions over cell ids."""
    only = re.compile(cfg["only"]) if cfg.get("only") else None
    skip = re.compile(cfg["skip"]) if cfg.get("skip") else None
    out = []
    for dataset in cfg["datasets"]:
        for variant in cfg["variants"]:
            for seed in cfg["seeds"]:
                for budget in cfg["budgets"]:
                    for method in cfg["methods"]:
                        cell_id = "%s/%s/s%d/%s/%s" % (dataset, variant, seed, method, budget["name"])
                        if (only and not only.search(cell_id)) or (skip and skip.search(cell_id)):
                            continue
                        out.append({"id": cell_id, "dataset": dataset, "variant": variant, "seed": seed,
                                    "method": method, "budget": budget})
    return out


# ---------------------------------------------------------------------------------------
# Running commands

def write_atomic(path, text):
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    tmp = "%s.tmp-%d" % (path, os.getpid())
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, path)


def tail(path, lines=6):
    try:
        with open(path, errors="replace") as f:
            text = [l.rstrip() for l in f.readlines() if l.strip()]
    except OSError:
        return ""
    return " | ".join(text[-lines:])


class Runner:
    def __init__(self, args, cfg):
        self.atex = args.atex
        self.dry_run = args.dry_run
        self.deadline = time.monotonic() + args.deadline if args.deadline else None
        self.timeout = cfg["command_timeout"] or None
        self.log_path = None if args.dry_run else os.path.join(args.out, "commands.log")

    def remaining(self):
        return None if self.deadline is None else self.deadline - time.monotonic()

    def run(self, step, argv, stdout_path=None, stderr_path=None):
        """Runs atex with `argv`; returns (parsed JSON of stdout or None, wall seconds)."""
        cmd = [self.atex] + [str(a) for a in argv]
        if self.dry_run:
            print("  " + " ".join(shlex.quote(c) for c in cmd) + (" > " + stdout_path if stdout_path else ""))
            return None, 0.0
        remaining = self.remaining()
        if remaining is not None and remaining <= 0:
            raise Interrupted()
        limits = [x for x in (remaining, self.timeout) if x is not None]
        limit = min(limits) if limits else None
        deadline_binds = remaining is not None and (self.timeout is None or remaining <= self.timeout)
        for p in (stdout_path, stderr_path):
            if p:
                os.makedirs(os.path.dirname(p) or ".", exist_ok=True)
        out_tmp = stdout_path + ".partial" if stdout_path else None
        start = time.monotonic()
        with open(out_tmp or os.devnull, "w") as out, open(stderr_path or os.devnull, "w") as err:
            try:
                # Same process group as the harness: whatever stops the harness's group stops atex too.
                proc = subprocess.Popen(cmd, stdout=out, stderr=err)
            except OSError as e:
                raise StepFailed(step, "cannot run %s: %s" % (self.atex, e))
            try:
                rc = proc.wait(timeout=limit)
            except subprocess.TimeoutExpired:
                self._stop(proc)
                seconds = time.monotonic() - start
                self._log(cmd, "killed", seconds)
                if deadline_binds:
                    raise Interrupted(seconds)
                raise StepFailed(step, "timed out after %.0f s (command_timeout)" % seconds)
            except KeyboardInterrupt:  # Ctrl-C, or SIGTERM (see main): stop atex, leave the cell without a row
                self._stop(proc)
                seconds = time.monotonic() - start
                self._log(cmd, "interrupted", seconds)
                raise Interrupted(seconds)
        seconds = time.monotonic() - start
        self._log(cmd, rc, seconds)
        if rc != 0:
            reason = "exit status %d" % rc if rc > 0 else "killed by signal %d" % -rc
            raise StepFailed(step, "%s: %s" % (reason, tail(stderr_path) or "(no message)"))
        data = None
        if stdout_path:
            text = ""
            try:
                with open(out_tmp) as f:
                    text = f.read()
                data = json.loads(text)
            except (OSError, ValueError) as e:
                raise StepFailed(step, "stdout is not JSON (%s): %r" % (e, text[:200]))
            os.replace(out_tmp, stdout_path)
        return data, seconds

    @staticmethod
    def _stop(proc):
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()

    def _log(self, cmd, rc, seconds):
        if self.log_path:
            with open(self.log_path, "a") as f:
                f.write("%s rc=%s %.1fs %s\n" % (datetime.datetime.now().isoformat(timespec="seconds"), rc, seconds,
                                                 " ".join(shlex.quote(c) for c in cmd)))


# ---------------------------------------------------------------------------------------
# The matrix

def read_json(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def finite(x):
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


class Matrix:
    def __init__(self, args, cfg):
        self.args = args
        self.cfg = cfg
        self.out = args.out
        self.run = Runner(args, cfg)
        self.memo_fail = {}  # artefact path -> StepFailed (no retry within one invocation)
        self.planned = set()  # --dry-run: models whose training was printed already

    # ---- artefacts ------------------------------------------------------------------
    def model_dir(self, cell):
        return os.path.join(self.out, "models", cell["dataset"], cell["variant"], "s%d" % cell["seed"])

    def data_args(self, cell, for_eval=False):
        d = self.cfg["datasets"][cell["dataset"]]
        v = self.cfg["variants"][cell["variant"]]
        return ["--data", expand_env(d["path"])] + d["args"] + (v["eval_args"] if for_eval else v["args"])

    def trained(self, cell, stage_name, argv, stage_cfg):
        """Trains (or reuses) one model; returns (path, train JSON, its attempts [{seconds, resumed, result}])."""
        base = os.path.join(self.model_dir(cell), stage_name)
        model, report = base + ".atex", base + ".train.json"
        if base in self.memo_fail:
            raise self.memo_fail[base]
        if self.args.dry_run:
            if base in self.planned:
                print("  # reuses %s" % model)
                return model, None, []
            self.planned.add(base)
        attempts_path = base + ".attempts.json"
        attempts = read_json(attempts_path) or []
        if not self.args.dry_run and os.path.exists(model) and read_json(report) is not None:
            return model, read_json(report), attempts
        ckpt = base + ".ckpt"
        argv = argv + ["--out", model, "--json", "--seed", str(cell["seed"]), "--backend", self.cfg["backend"],
                       "--checkpoint-dir", ckpt, "--checkpoint-every", str(stage_cfg["checkpoint_every"])]
        per_stage = self.args.stage1_time_limit if stage_name == "stage1" else self.args.stage2_time_limit
        time_limit = per_stage or self.args.time_limit or stage_cfg.get("time_limit") or 0
        if time_limit:
            argv += ["--time-limit", str(time_limit)]
        resumed = os.path.exists(os.path.join(ckpt, "trainer.json"))
        if resumed:
            argv += ["--resume", ckpt]
        try:
            data, seconds = self.run.run("train " + stage_name, ["train"] + argv, report, base + ".log")
        except Interrupted as e:
            self.attempt(attempts_path, attempts, e.seconds, resumed, "interrupted")
            raise
        except StepFailed as e:
            self.memo_fail[base] = e
            raise
        if self.args.dry_run:
            return model, None, []
        self.attempt(attempts_path, attempts, seconds, resumed, "ok")
        shutil.rmtree(ckpt, ignore_errors=True)  # the model is complete: its checkpoint is no longer needed
        return model, data, attempts

    def attempt(self, path, attempts, seconds, resumed, result):
        """Training attempts (wall seconds each), so that a run resumed after --deadline is timed in full."""
        attempts.append({"seconds": round(seconds, 3), "resumed": resumed, "result": result})
        if not self.args.dry_run:
            write_atomic(path, json.dumps(attempts, indent=1))

    def stage1(self, cell):
        s1 = self.cfg["stage1"]
        return self.trained(cell, "stage1", self.data_args(cell) + ["--stage", "1"] + s1["args"], s1)

    def stage2(self, cell, method_name, stage1_path):
        m = self.cfg["methods"][method_name]
        s2 = self.cfg["stage2"]
        argv = self.data_args(cell) + ["--stage", "2", "--init", stage1_path, "--textures", m["textures"]]
        for kv in m["set"]:
            argv += ["--set", kv]
        argv += s2["args"] + m["args"]
        return self.trained(cell, method_name, argv, s2)

    def method_model(self, cell, method_name, s1_path, s1_report, s1_wall):
        """(model path, {stage: train JSON}, {stage: wall s}) of a method without budget fitting."""
        if not self.cfg["methods"][method_name]["stage2"]:
            return s1_path, {"stage1": s1_report}, {"stage1": s1_wall}
        path, report, wall = self.stage2(cell, method_name, s1_path)
        return path, {"stage1": s1_report, "stage2": report}, {"stage1": s1_wall, "stage2": wall}

    def fitted(self, cell, model, s1_path):
        b = cell["budget"]
        fit = self.cfg["fit"]
        cell_dir = self.cell_dir(cell)
        out = os.path.join(cell_dir, "fit.atex")
        argv = ["fit", model, out]
        if b["kind"] == "keep_count":
            argv += ["--keep-count", str(b["keep_count"])]
            if b.get("order_from") == "stage1":
                argv += ["--order-from", s1_path]
        else:
            if "budget_mib" in b:
                size = float(b["budget_mib"]) * MIB
            else:  # a fraction of another method's (unfitted) model: train it first if needed
                ref_path, _, _ = self.method_model(cell, b["budget_of"], *self.stage1(cell))
                size = None if self.args.dry_run else float(b["fraction"]) * os.path.getsize(ref_path)
            if size is None:
                value = "<%g x size of %s model>" % (float(b["fraction"]), b["budget_of"])
            elif fit["budget_unit"] == "mib":
                value = "%.6f" % (size / MIB)
            else:
                value = str(int(size))
            argv += ["--budget", value]
        if fit["pass_data"]:
            d = self.cfg["datasets"][cell["dataset"]]
            argv += ["--data", expand_env(d["path"])] + \
                option_values(d["args"], ("--timesteps", "--downscale", "--dataset-kind"))
        argv += ["--backend", self.cfg["backend"]] + fit["args"] + ["--json"]
        data, seconds = self.run.run("fit", argv, os.path.join(cell_dir, "fit.json"),
                                     os.path.join(cell_dir, "fit.log"))
        if isinstance(data, dict) and isinstance(data.get("moves"), list):  # keep rows small
            data = dict(data, moves=len(data["moves"]))
        return out, data, seconds

    def cell_dir(self, cell):
        return os.path.join(self.out, "cells", re.sub(r"[^A-Za-z0-9_.=-]+", "_", cell["id"]))

    # ---- one cell ---------------------------------------------------------------------
    def run_cell(self, cell):
        row = {"cell": cell["id"], "config": self.cfg["name"], "dataset": cell["dataset"],
               "variant": cell["variant"], "seed": cell["seed"], "method": cell["method"],
               "budget": cell["budget"]["name"], "budget_kind": cell["budget"]["kind"]}
        try:
            s1_path, s1_report, s1_wall = self.stage1(cell)
            model, reports, walls = self.method_model(cell, cell["method"], s1_path, s1_report, s1_wall)
            if cell["budget"]["kind"] != "full":
                model, fit_report, fit_seconds = self.fitted(cell, model, s1_path)
                row["fit"] = fit_report
                row["fit_s"] = fit_seconds
            self.measure(cell, model, row)
            self.add_training(row, reports, walls)
            self.check(row)
        except StepFailed as e:
            row["status"] = "failed"
            row["failed_step"] = e.step
            row["cause"] = e.cause
            return row
        row["status"] = "ok"
        return row

    def measure(self, cell, model, row):
        cell_dir = self.cell_dir(cell)
        j = lambda name: os.path.join(cell_dir, name)
        eval_argv = ["eval", model] + self.data_args(cell, for_eval=True) + self.cfg["eval"]["args"] + \
                    ["--backend", self.cfg["backend"], "--json"]
        ev, _ = self.run.run("eval", eval_argv, j("eval.json"), j("eval.log"))
        info, _ = self.run.run("info", ["info", model, "--json"], j("info.json"), j("info.log"))
        fps_cfg = self.cfg["fps"]
        dataset = self.cfg["datasets"][cell["dataset"]]
        fps = {}
        for size in ([] if self.args.skip_fps else fps_cfg["sizes"]):
            argv = ["fps", model, "--data", expand_env(dataset["path"])] + dataset["fps_args"] + \
                   ["--view", fps_cfg["view"], "--repeats", str(fps_cfg["repeats"]), "--backend", self.cfg["backend"],
                    "--json"]
            if size != "native":
                argv += ["--size", size]
            fps[size], _ = self.run.run("fps " + size, argv, j("fps.%s.json" % size), j("fps.%s.log" % size))
        if self.args.dry_run:
            return
        row["model"] = model
        row["model_bytes"] = os.path.getsize(model)
        row["model_mib"] = row["model_bytes"] / MIB
        self.add_eval(row, ev)
        self.add_info(row, info)
        for size, f in fps.items():
            key = "native" if size == "native" else size
            row["fps_" + key] = f.get("fps") if isinstance(f, dict) else None
            if size == "native" and isinstance(f, dict):
                row["native_size"] = "%sx%s" % (f.get("width"), f.get("height"))
                row["render_backend"] = f.get("backend")

    @staticmethod
    def add_eval(row, ev):
        if not isinstance(ev, dict) or not isinstance(ev.get("mean"), dict):
            raise StepFailed("eval", "eval JSON has no 'mean'")
        for k in ("psnr", "ssim", "dssim1", "dssim2", "l1"):
            row[k] = ev["mean"].get(k)
        row["cameras"] = [{k: c.get(k) for k in ("camera", "views", "psnr", "ssim", "dssim1", "dssim2")}
                          for c in ev.get("cameras", [])]
        # Per view (camera, timestep, psnr, ssim, dssim1, dssim2): the paired bootstrap's input.
        row["views"] = [[v.get("camera"), v.get("timestep"), v.get("psnr"), v.get("ssim"), v.get("dssim1"),
                         v.get("dssim2")] for v in ev.get("views", [])]
        row["eval_backend"] = ev.get("backend")

    @staticmethod
    def add_info(row, info):
        if not isinstance(info, dict):
            raise StepFailed("info", "info JSON is not an object")
        row["gaussians"] = info.get("gaussians")
        t = info.get("textures") or {}
        row["texture_mode"] = t.get("mode")
        if t.get("present"):
            row["texture_bytes"] = t.get("stored_bytes")
            row["texture_mib"] = t.get("stored_bytes", 0) / MIB
            row["texel_bytes"] = t.get("texel_bytes")
            row["uniform_texel_bytes"] = t.get("uniform_4x4_texel_bytes")
            row["texels"] = t.get("texels")
            row["uniform_texels"] = t.get("uniform_4x4_texels")
            row["histogram"] = {k: (t.get("histogram_hxw") or {}).get(k, 0) for k in HIST_KEYS}
        else:
            row["texture_bytes"] = 0
            row["texture_mib"] = 0.0
        row["components"] = {c.get("component"): c.get("bytes") for c in info.get("components", [])}

    @staticmethod
    def add_training(row, reports, walls):
        peaks = []
        rollbacks = 0
        for stage, rep in reports.items():
            if not isinstance(rep, dict):
                continue
            sec = rep.get("seconds") or {}
            if stage == "stage1":
                row["train_s_stage1"] = (sec.get("coarse") or 0) + (sec.get("fine") or 0)
            else:
                row["train_s_stage2"] = sec.get("textures") or 0
            attempts = walls.get(stage) or []
            row["train_wall_s_" + stage] = sum(a.get("seconds", 0) for a in attempts)
            # Resumed runs are not bit-identical to uninterrupted ones in stage 2 (the growth
            # statistics since the last growth are not checkpointed): count them.
            row["train_resumes_" + stage] = sum(1 for a in attempts if a.get("resumed"))
            row["peak_gpu_bytes_" + stage] = rep.get("peak_memory_bytes")
            peaks.append(rep.get("peak_memory_bytes") or 0)
            row["stopped_by_time_limit_" + stage] = rep.get("stopped_by_time_limit")
            rollbacks += sum(1 for e in rep.get("events", []) if "rolled back" in str(e))
            row["train_backend"] = rep.get("backend")
        row["peak_gpu_gib"] = max(peaks) / float(1 << 30) if peaks else None
        row["train_s_total"] = (row.get("train_s_stage1") or 0) + (row.get("train_s_stage2") or 0) + \
            (row.get("fit_s") or 0)
        row["rollbacks"] = rollbacks

    def check(self, row):
        for k in ("psnr", "ssim", "dssim1", "dssim2"):
            if not finite(row.get(k)):
                raise StepFailed("eval", "mean %s is %s (NaN, or +inf PSNR for a view identical to its target, "
                                         "which the JSON writes as null)" % (k, row.get(k)))
        if row["psnr"] < float(self.cfg["psnr_floor"]):
            raise StepFailed("quality", "mean test PSNR %.2f dB is below the floor of %s dB" %
                             (row["psnr"], self.cfg["psnr_floor"]))
        if not row.get("gaussians"):
            raise StepFailed("collapse", "the model has no Gaussians")


# ---------------------------------------------------------------------------------------
# Results

CSV_FIXED = ["cell", "config", "dataset", "variant", "seed", "method", "budget", "budget_kind", "status",
             "failed_step", "cause", "psnr", "ssim", "dssim1", "dssim2", "texture_mib", "model_mib", "model_bytes",
             "gaussians", "texels", "uniform_texels", "texel_bytes", "uniform_texel_bytes"] + \
            ["hist_" + k for k in HIST_KEYS] + \
            ["peak_gpu_gib", "train_s_stage1", "train_s_stage2", "fit_s", "train_s_total", "train_wall_s_stage1",
             "train_wall_s_stage2", "train_resumes_stage1", "train_resumes_stage2", "stopped_by_time_limit_stage1",
             "stopped_by_time_limit_stage2", "rollbacks", "native_size", "fps_native"]


def clean(value):
    """NaN/Inf -> None (rows are strict JSON), recursively."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: clean(v) for k, v in value.items()}
    if isinstance(value, list):
        return [clean(v) for v in value]
    return value


def load_rows(path):
    """The last row of every cell in a results.jsonl (later rows replace earlier ones)."""
    rows = {}
    if not os.path.exists(path):
        return rows
    with open(path) as f:
        for n, line in enumerate(f, 1):
            line = line.strip()
            if not line:
                continue
            try:
                row = json.loads(line)
            except ValueError:
                print("run_matrix: %s:%d: unreadable line skipped (a run killed while writing?)" % (path, n),
                      file=sys.stderr)
                continue
            if isinstance(row, dict) and "cell" in row:
                rows[row["cell"]] = row
    return rows


def write_csv(rows, path):
    fps_cols = sorted({k for r in rows for k in r if k.startswith("fps_") and k != "fps_native"})
    cams = sorted({c["camera"] for r in rows for c in r.get("cameras", []) if c.get("camera") is not None})
    cam_cols = ["%s_cam%d" % (m, c) for c in cams for m in ("psnr", "ssim", "dssim1", "dssim2")]
    header = CSV_FIXED + fps_cols + cam_cols
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for r in rows:
        flat = dict(r)
        for k, v in (r.get("histogram") or {}).items():
            flat["hist_" + k] = v
        for c in r.get("cameras", []):
            for m in ("psnr", "ssim", "dssim1", "dssim2"):
                flat["%s_cam%s" % (m, c.get("camera"))] = c.get(m)
        out = []
        for h in header:
            v = flat.get(h)
            if v is None:
                out.append("")
            elif isinstance(v, float):
                out.append("%.6g" % v)
            else:
                out.append(str(v))
        w.writerow(out)
    write_atomic(path, buf.getvalue())


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog="See the module docstring (head -60 bench/run_matrix.py) for the config format.")
    p.add_argument("config", help="JSON experiment config (bench/configs/*.json)")
    p.add_argument("--atex", default=None, help="the atex binary (default: $ATEX, else build/bin/atex)")
    p.add_argument("--out", default=None, help="results folder (default: out/<config name>, which git ignores)")
    p.add_argument("--dry-run", action="store_true", help="print the commands of every selected cell; run nothing")
    p.add_argument("--list", action="store_true", help="list the cells and whether they have a row; run nothing")
    p.add_argument("--only", default=None, metavar="CELLREGEX",
                   help="run only cells whose id (dataset/variant/sSEED/method/budget) matches (re.search)")
    p.add_argument("--time-limit", type=float, default=0,
                   help="pass --time-limit S to every `atex train` (the model is written when it stops; "
                        "overrides the config's stage1/stage2 time_limit)")
    p.add_argument("--stage1-time-limit", type=float, default=0, help="--time-limit for stage 1 only")
    p.add_argument("--stage2-time-limit", type=float, default=0, help="--time-limit for stage 2 only")
    p.add_argument("--deadline", type=float, default=0,
                   help="stop after S seconds of wall time: the running command is killed, its cell gets no row, "
                        "and the exit status is 3 (rerun to continue; training resumes from its checkpoint)")
    p.add_argument("--retry-failed", action="store_true", help="run cells whose row is a failure again")
    p.add_argument("--skip-fps", action="store_true",
                   help="no `atex fps` (rows get no FPS columns), e.g. while another job shares the GPU")
    args = p.parse_args(argv)
    try:
        cfg = load_config(args.config)
        selected = cells(cfg)
        if args.only:
            rx = re.compile(args.only)
            selected = [c for c in selected if rx.search(c["id"])]
    except (ConfigError, re.error) as e:
        print("run_matrix: %s" % e, file=sys.stderr)
        return EXIT_USAGE
    args.atex = args.atex or os.environ.get("ATEX") or os.path.join("build", "bin", "atex")
    args.out = args.out or os.path.join("out", cfg["name"])
    results = os.path.join(args.out, "results.jsonl")
    rows = load_rows(results)

    if args.list:
        for c in selected:
            r = rows.get(c["id"])
            print("%-60s %s" % (c["id"], r["status"] if r else "-"))
        return EXIT_COMPLETE
    if not args.dry_run:
        if not (os.path.isfile(args.atex) and os.access(args.atex, os.X_OK)):
            print("run_matrix: %s is not an executable (use --atex or $ATEX)" % args.atex, file=sys.stderr)
            return EXIT_USAGE
        os.makedirs(args.out, exist_ok=True)
    def on_sigterm(signum, frame):
        raise KeyboardInterrupt()
    signal.signal(signal.SIGTERM, on_sigterm)
    matrix = Matrix(args, cfg)
    counts = {"ok": 0, "failed": 0, "skipped": 0}
    interrupted = False
    for c in selected:
        old = rows.get(c["id"])
        if old and (old.get("status") == "ok" or not args.retry_failed):
            counts["skipped"] += 1
            if args.dry_run:
                print("# %s: has a row (%s), skipped" % (c["id"], old.get("status")))
            continue
        if args.dry_run:
            print("# cell %s" % c["id"])
        start = time.monotonic()
        try:
            row = matrix.run_cell(c)
        except (Interrupted, KeyboardInterrupt):
            interrupted = True
            print("run_matrix: stopped (deadline or signal) during %s; rerun the same command to continue" % c["id"],
                  file=sys.stderr)
            break
        if args.dry_run:
            continue
        row["cell_wall_s"] = round(time.monotonic() - start, 3)
        row["finished"] = datetime.datetime.now().isoformat(timespec="seconds")
        row = clean(row)
        with open(results, "a") as f:
            f.write(json.dumps(row, allow_nan=False, default=str) + "\n")
        rows[c["id"]] = row
        write_csv(list(rows.values()), os.path.join(args.out, "results.csv"))
        counts[row["status"]] += 1
        what = "ok   PSNR %.3f" % row["psnr"] if row["status"] == "ok" else \
            "FAILED at %s: %s" % (row["failed_step"], row["cause"])
        print("%-60s %s (%.0f s)" % (c["id"], what, row["cell_wall_s"]), flush=True)
    if args.dry_run:
        return EXIT_COMPLETE
    if rows:
        write_csv(list(rows.values()), os.path.join(args.out, "results.csv"))
    print("run_matrix: %d ok, %d failed, %d skipped (had rows)%s; results in %s" %
          (counts["ok"], counts["failed"], counts["skipped"], ", INCOMPLETE" if interrupted else "", args.out))
    return EXIT_INCOMPLETE if interrupted else EXIT_COMPLETE


if __name__ == "__main__":
    sys.exit(main())
