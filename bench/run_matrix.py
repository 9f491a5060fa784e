#!/usr/bin/env python3
"""Run an experiment matrix of `atex` commands from a JSON config (issue 9).

    python3 bench/run_matrix.py CONFIG.json [--atex PATH] [--out DIR] [--dry-run] [--list]
                                [--only REGEX] [--time-limit S] [--stage1-time-limit S] [--stage2-time-limit S]
                                [--deadline S] [--retry-failed] [--skip-fps] [--gpus LIST]

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

Several GPUs (--gpus 0,1,2,3): one worker thread per listed device runs whole cells; every atex
command it starts sees CUDA_VISIBLE_DEVICES=<device> (replacing an inherited one: LIST holds the
machine's device indices) and OMP_NUM_THREADS=<cpus / number of devices> (unless OMP_NUM_THREADS is
set already). Models are still trained once: a worker takes the first
pending cell none of whose missing models (stage 1, the method's stage 2, a budget_of method's model)
another worker is training right now, and waits when there is none. Rows get a "gpu" field. While a
worker runs a cell it holds an exclusive flock on ${TMPDIR:-/tmp}/atex_run_matrix_gpu<N>.lock, so
run_matrix processes started with overlapping --gpus lists (e.g. two configs at once) take turns on
a GPU, cell by cell, and never share it. Without --gpus, cells run one after another and atex gets
the environment unchanged; --dry-run and --list ignore --gpus.

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
                  (a budget's "args": [...] go to its `atex fit` after fit.args, e.g. ["--levers", "prune"])
  fit             {"args": [...], "pass_data": true, "budget_unit": "bytes" | "mib"}   (pass_data: --data and
                  the dataset's --timesteps/--downscale/--dataset-kind; --backend is always passed)
  fps             {"sizes": ["native", "1352x1014"], "repeats": 100, "view": "test:0"}
  eval            {"args": [...], "train_split": false}   (train_split: also `atex eval --split train`, giving
                  the row's train_psnr/train_ssim: how much of the test score is fit and how much is held out)
  backend         "auto" | "cuda" | "cpu"          (passed as --backend to train/eval/fps)
  only, skip      regular expressions over cell ids that restrict the cross product
  psnr_floor      cells below this mean test PSNR are failure rows (default 10)
  command_timeout seconds; a command running longer is killed and its cell fails (default: none)
"""

import argparse
import csv
import datetime
import fcntl
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
import threading
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
        b["args"] = as_list(b.get("args"), "budget %s args" % b["name"])
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
    ev.setdefault("train_split", False)
    if not isinstance(ev["train_split"], bool):
        raise ConfigError("eval.train_split: true or false")
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
    tmp = "%s.tmp-%d-%d" % (path, os.getpid(), threading.get_ident())  # unique per worker thread too
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


def in_worker_thread():
    return threading.current_thread() is not threading.main_thread()


class Runner:
    """Runs atex commands, from the main thread or from several GPU worker threads at once."""

    def __init__(self, args, cfg):
        self.atex = args.atex
        self.dry_run = args.dry_run
        self.deadline = time.monotonic() + args.deadline if args.deadline else None
        self.timeout = cfg["command_timeout"] or None
        self.log_path = None if args.dry_run else os.path.join(args.out, "commands.log")
        self.local = threading.local()  # .env: the environment of this thread's commands (None: inherit)
        self.lock = threading.Lock()  # guards procs, stopping and commands.log
        self.procs = set()  # the running commands, so that a stop (SIGTERM, Ctrl-C) reaches all of them
        self.stopping = threading.Event()  # set by stop_all: no new commands, running ones are Interrupted

    def use_env(self, env):
        """The environment of the commands that the calling thread runs from now on (a GPU worker's)."""
        self.local.env = env

    def remaining(self):
        return None if self.deadline is None else self.deadline - time.monotonic()

    def expired(self):
        remaining = self.remaining()
        return remaining is not None and remaining <= 0

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
            proc = self._start(step, cmd, out, err)
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
            finally:
                with self.lock:
                    self.procs.discard(proc)
        seconds = time.monotonic() - start
        if rc != 0 and self._stopped_by_us(rc):
            self._log(cmd, "interrupted", seconds)
            raise Interrupted(seconds)
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

    def _start(self, step, cmd, out, err):
        # Checked and registered under the lock, so that stop_all cannot miss a command starting now.
        with self.lock:
            if self.stopping.is_set():
                raise Interrupted()
            try:
                # Same process group as the harness: whatever stops the harness's group stops atex too.
                proc = subprocess.Popen(cmd, stdout=out, stderr=err, env=getattr(self.local, "env", None))
            except OSError as e:
                raise StepFailed(step, "cannot run %s: %s" % (self.atex, e))
            self.procs.add(proc)
            return proc

    def _stopped_by_us(self, rc):
        """Whether a failed command was stopped by stop_all (its cell gets no row) rather than failing."""
        if self.stopping.is_set():
            return True
        # Ctrl-C reaches the whole process group: atex (no signal handlers of its own) may die of SIGINT
        # before the main thread (the only one Python signals) has called stop_all. Give it a moment
        # rather than writing a failure row.
        if in_worker_thread() and rc in (-signal.SIGINT, -signal.SIGTERM):
            return self.stopping.wait(2.0)
        return False

    def stop_all(self, kill=False):
        """Terminates (kill: kills) every running command and refuses new ones; the workers' run()
        calls raise Interrupted. Used by the main thread on SIGTERM / Ctrl-C with --gpus."""
        with self.lock:
            self.stopping.set()
            procs = list(self.procs)
        for proc in procs:
            try:
                if kill:
                    proc.kill()
                else:
                    proc.terminate()
            except OSError:  # exited meanwhile
                pass

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
            with self.lock, open(self.log_path, "a") as f:
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
        self.lock = threading.Lock()  # guards memo_fail, planned and the attempts files (GPU workers)
        # Called with a model's base path when its training ended (ok, failed or interrupted): the
        # GPU scheduler lets other workers use (or fail on) that model from then on.
        self.model_done = lambda base: None

    # ---- artefacts ------------------------------------------------------------------
    def model_dir(self, cell):
        return os.path.join(self.out, "models", cell["dataset"], cell["variant"], "s%d" % cell["seed"])

    def data_args(self, cell, for_eval=False):
        d = self.cfg["datasets"][cell["dataset"]]
        v = self.cfg["variants"][cell["variant"]]
        return ["--data", expand_env(d["path"])] + d["args"] + (v["eval_args"] if for_eval else v["args"])

    def model_base(self, cell, stage_name):
        """A trained model's path without extension (.atex, .train.json, .attempts.json, .ckpt, .log)."""
        return os.path.join(self.model_dir(cell), stage_name)

    @staticmethod
    def model_ready(base):
        """Whether the model was trained completely (the same test as trained()'s reuse)."""
        return os.path.exists(base + ".atex") and read_json(base + ".train.json") is not None

    def artefacts(self, cell):
        """The base paths of the models that run_cell(cell) trains or reuses: the stage-1 model, the
        method's stage-2 model, and for a budget_of budget the referenced method's model (the same
        choices as stage1 / method_model / fitted make)."""
        methods = self.cfg["methods"]
        needed = [self.model_base(cell, "stage1")]
        if methods[cell["method"]]["stage2"]:
            needed.append(self.model_base(cell, cell["method"]))
        b = cell["budget"]
        if b["kind"] == "budget" and "budget_mib" not in b and methods[b["budget_of"]]["stage2"]:
            ref = self.model_base(cell, b["budget_of"])
            if ref not in needed:
                needed.append(ref)
        return needed

    def trained(self, cell, stage_name, argv, stage_cfg):
        """Trains (or reuses) one model; returns (path, train JSON, its attempts [{seconds, resumed, result}])."""
        base = self.model_base(cell, stage_name)
        model, report = base + ".atex", base + ".train.json"
        with self.lock:
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
        # --force: the harness owns its outputs (a model without its report is retrained in place).
        argv = argv + ["--out", model, "--force", "--json", "--seed", str(cell["seed"]), "--backend", self.cfg["backend"],
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
            if self.args.dry_run:
                return model, None, []
            self.attempt(attempts_path, attempts, seconds, resumed, "ok")
            shutil.rmtree(ckpt, ignore_errors=True)  # the model is complete: its checkpoint is no longer needed
            return model, data, attempts
        except Interrupted as e:
            self.attempt(attempts_path, attempts, e.seconds, resumed, "interrupted")
            raise
        except StepFailed as e:
            with self.lock:
                self.memo_fail[base] = e
            raise
        finally:  # after the attempt and memo_fail are recorded: others may use the model (or its failure)
            self.model_done(base)

    def attempt(self, path, attempts, seconds, resumed, result):
        """Training attempts (wall seconds each), so that a run resumed after --deadline is timed in full."""
        attempts.append({"seconds": round(seconds, 3), "resumed": resumed, "result": result})
        if not self.args.dry_run:
            with self.lock:
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
        argv = ["fit", model, out, "--force"]  # a cell re-run replaces its own fit
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
        argv += ["--backend", self.cfg["backend"]] + fit["args"] + b["args"] + ["--json"]
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
        train_ev = None
        if self.cfg["eval"]["train_split"]:
            train_ev, _ = self.run.run("eval train", eval_argv + ["--split", "train"], j("eval_train.json"),
                                       j("eval_train.log"))
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
        if train_ev is not None:
            if not isinstance(train_ev, dict) or not isinstance(train_ev.get("mean"), dict):
                raise StepFailed("eval train", "eval JSON has no 'mean'")
            row["train_psnr"] = train_ev["mean"].get("psnr")
            row["train_ssim"] = train_ev["mean"].get("ssim")
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
        for k in ("psnr", "ssim", "dssim1", "dssim2", "l1", "dynamic_psnr"):
            row[k] = ev["mean"].get(k)
        row["cameras"] = [{k: c.get(k) for k in ("camera", "views", "psnr", "ssim", "dssim1", "dssim2",
                                                 "dynamic_psnr", "dynamic_fraction")}
                          for c in ev.get("cameras", [])]
        # Per view (camera, timestep, psnr, ssim, dssim1, dssim2, dynamic_psnr): the paired bootstrap's input.
        row["views"] = [[v.get("camera"), v.get("timestep"), v.get("psnr"), v.get("ssim"), v.get("dssim1"),
                         v.get("dssim2"), v.get("dynamic_psnr")] for v in ev.get("views", [])]
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
             "failed_step", "cause", "psnr", "ssim", "dssim1", "dssim2", "dynamic_psnr", "texture_mib", "model_mib", "model_bytes",
             "gaussians", "texels", "uniform_texels", "texel_bytes", "uniform_texel_bytes"] + \
            ["hist_" + k for k in HIST_KEYS] + \
            ["peak_gpu_gib", "train_s_stage1", "train_s_stage2", "fit_s", "train_s_total", "train_wall_s_stage1",
             "train_wall_s_stage2", "train_resumes_stage1", "train_resumes_stage2", "stopped_by_time_limit_stage1",
             "stopped_by_time_limit_stage2", "rollbacks", "native_size", "fps_native"]


CAMERA_METRICS = ("psnr", "ssim", "dssim1", "dssim2", "dynamic_psnr")


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
    cam_cols = ["%s_cam%d" % (m, c) for c in cams for m in CAMERA_METRICS]
    gpu_col = ["gpu"] if any("gpu" in r for r in rows) else []  # only from runs with --gpus
    train_cols = ["train_psnr", "train_ssim"] if any("train_psnr" in r for r in rows) else []  # eval.train_split
    header = CSV_FIXED + gpu_col + train_cols + fps_cols + cam_cols
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for r in rows:
        flat = dict(r)
        for k, v in (r.get("histogram") or {}).items():
            flat["hist_" + k] = v
        for c in r.get("cameras", []):
            for m in CAMERA_METRICS:
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


class Results:
    """results.jsonl, results.csv, the per-cell progress line and the counts, behind one lock so that
    GPU workers can record rows concurrently."""

    def __init__(self, out, rows):
        self.jsonl = os.path.join(out, "results.jsonl")
        self.csv = os.path.join(out, "results.csv")
        self.rows = rows  # cell id -> its last row
        self.counts = {"ok": 0, "failed": 0, "skipped": 0}
        self.lock = threading.Lock()

    def add(self, cell, row, start, gpu=None):
        row["cell_wall_s"] = round(time.monotonic() - start, 3)
        row["finished"] = datetime.datetime.now().isoformat(timespec="seconds")
        if gpu is not None:
            row["gpu"] = str(gpu)
        row = clean(row)
        with self.lock:
            with open(self.jsonl, "a") as f:
                f.write(json.dumps(row, allow_nan=False, default=str) + "\n")
            self.rows[cell["id"]] = row
            write_csv(list(self.rows.values()), self.csv)
            self.counts[row["status"]] += 1
            what = "ok   PSNR %.3f" % row["psnr"] if row["status"] == "ok" else \
                "FAILED at %s: %s" % (row["failed_step"], row["cause"])
            print("%-60s %s (%.0f s)%s" % (cell["id"], what, row["cell_wall_s"],
                                           "" if gpu is None else " [gpu %s]" % gpu), flush=True)


# ---------------------------------------------------------------------------------------
# Several GPUs (--gpus)

def parse_gpus(text):
    """--gpus LIST: comma-separated, distinct, non-negative device indices."""
    items = text.split(",")
    if not all(re.fullmatch(r"\d+", i.strip()) for i in items):
        raise argparse.ArgumentTypeError("%r: expected device indices like 0,1,2,3" % text)
    gpus = [int(i) for i in items]
    if len(set(gpus)) != len(gpus):
        raise argparse.ArgumentTypeError("%r: a device is listed twice" % text)
    return gpus


def gpu_env(gpu, count):
    """The environment of a worker's atex commands: its device only, and its share of the CPU cores
    (OpenMP would otherwise start one thread per core in every worker's process)."""
    env = dict(os.environ, CUDA_VISIBLE_DEVICES=str(gpu))
    if not os.environ.get("OMP_NUM_THREADS"):
        env["OMP_NUM_THREADS"] = str(max(1, (os.cpu_count() or 1) // count))
    return env


class GpuLock:
    """An exclusive flock on ${TMPDIR:-/tmp}/atex_run_matrix_gpu<N>.lock: run_matrix processes (any
    config, any --out) started with overlapping --gpus lists never run cells on one GPU at once."""

    def __init__(self, gpu):
        self.path = os.path.join(os.environ.get("TMPDIR") or "/tmp", "atex_run_matrix_gpu%d.lock" % gpu)
        try:  # read-only is enough for flock; an existing file may belong to another user
            self.fd = os.open(self.path, os.O_RDONLY)
        except FileNotFoundError:
            self.fd = os.open(self.path, os.O_RDONLY | os.O_CREAT, 0o666)

    def acquire(self, give_up):
        """Polls (non-blocking, so that a stop or the deadline is noticed) until the lock is ours
        (True) or give_up() says to stop waiting (False)."""
        while True:
            try:
                fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                return True
            except BlockingIOError:
                if give_up():
                    return False
                time.sleep(0.1)

    def release(self):
        fcntl.flock(self.fd, fcntl.LOCK_UN)

    def close(self):
        os.close(self.fd)


class Scheduler:
    """Hands the pending cells to the GPU workers, in cell order, so that no model is trained by two
    workers at once: a cell is taken only if none of its missing models is being trained by another
    worker right now. Also the shared stop flag: after a stop nobody takes a new cell."""

    def __init__(self, matrix, pending):
        self.matrix = matrix
        self.pending = list(pending)
        self.training = {}  # model base path -> the GPU whose worker may train it now
        self.stopped = False
        self.cond = threading.Condition()
        matrix.model_done = lambda base: self.release([base])

    def give_up(self):
        """Whether a worker should stop waiting (for its GPU lock or a cell): stopped, deadline, no work."""
        return self.stopped or not self.pending or self.matrix.run.expired()

    WAIT = "wait"

    def take(self, gpu):
        """(cell, the models its worker may train); WAIT when every pending cell needs a model that
        another worker is training right now; None when there is nothing (more) to do."""
        with self.cond:
            if self.give_up():
                return None
            for i, cell in enumerate(self.pending):
                # A model that failed in this run is not ready either: its cell is taken and fails fast.
                todo = [b for b in self.matrix.artefacts(cell) if not self.matrix.model_ready(b)]
                if not any(b in self.training for b in todo):
                    del self.pending[i]
                    self.training.update(dict.fromkeys(todo, gpu))
                    return cell, todo
            return self.WAIT

    def wait_for_change(self, seconds=0.5):
        """Waits until a model is released or a stop (or `seconds`: the deadline passes without a notify)."""
        with self.cond:
            if not self.give_up():
                self.cond.wait(timeout=seconds)

    def release(self, bases):
        with self.cond:
            for b in bases:
                self.training.pop(b, None)
            self.cond.notify_all()

    def stop(self):
        with self.cond:
            self.stopped = True
            self.cond.notify_all()


def gpu_worker(gpu, matrix, scheduler, results, env):
    """One GPU's thread: takes the GPU's lock, then a cell, runs it, writes its row, releases the lock."""
    matrix.run.use_env(env)
    lock = GpuLock(gpu)
    try:
        while lock.acquire(scheduler.give_up):
            taken = None
            try:
                taken = scheduler.take(gpu)
                if taken is None:
                    return
                if taken is not Scheduler.WAIT:
                    cell, todo = taken
                    start = time.monotonic()
                    try:
                        row = matrix.run_cell(cell)
                    except Interrupted:
                        # The deadline or a signal: no row, and no new cell for any worker. The others'
                        # running commands go on until the deadline (or stop_all) stops them too.
                        scheduler.stop()
                        print("run_matrix: stopped (deadline or signal) during %s [gpu %d]; rerun the same "
                              "command to continue" % (cell["id"], gpu), file=sys.stderr, flush=True)
                        return
                    finally:
                        scheduler.release(todo)  # the models it did not get to (e.g. after a stage-1 failure)
                    results.add(cell, row, start, gpu)
            finally:
                lock.release()
            if taken is Scheduler.WAIT:
                # Waits without the GPU's lock, so that another process (another config) can use the GPU
                # while this one's cells wait for a model that another of its workers is training.
                scheduler.wait_for_change()
    finally:
        lock.close()


def wait_threads(threads, seconds, give_up=lambda: False):
    """Waits up to `seconds` for the threads to end (polling, so that give_up() is noticed)."""
    end = time.monotonic() + seconds
    while any(t.is_alive() for t in threads) and time.monotonic() < end and not give_up():
        time.sleep(0.1)


def run_parallel(matrix, pending, gpus, results):
    """Runs the pending cells on one worker thread per GPU; returns whether the matrix is incomplete.

    Python delivers signals to the main thread only, so it handles SIGTERM / Ctrl-C for all workers:
    it stops every running command (Runner.stop_all; the workers' run() calls raise Interrupted) and
    waits for the workers. Its handlers only record the signal: a KeyboardInterrupt raised inside
    Thread.join() can mark a live thread as finished (CPython 3.11's _wait_for_tstate_lock), and the
    harness would exit under a worker that is still writing its attempt record."""
    scheduler = Scheduler(matrix, pending)
    errors = []
    signals = []

    def work(gpu):
        try:
            gpu_worker(gpu, matrix, scheduler, results, gpu_env(gpu, len(gpus)))
        except BaseException as e:  # a bug or an I/O error: no new cells (the others finish theirs), then
            # the main thread raises it
            errors.append(e)
            scheduler.stop()

    def on_signal(signum, frame):
        signals.append(signum)

    for signum in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(signum) is not signal.SIG_IGN:  # an ignored SIGINT (a background job) stays so
            signal.signal(signum, on_signal)
    threads = [threading.Thread(target=work, args=(gpu,), name="gpu%d" % gpu, daemon=True) for gpu in gpus]
    for t in threads:
        t.start()
    wait_threads(threads, float("inf"), give_up=lambda: bool(signals))
    if signals:
        print("run_matrix: stopping every GPU's command", file=sys.stderr, flush=True)
        scheduler.stop()
        matrix.run.stop_all()
        # As Runner._stop: SIGTERM, then SIGKILL after a grace period (none after a second signal).
        wait_threads(threads, 10, give_up=lambda: len(signals) > 1)
        matrix.run.stop_all(kill=True)
    for t in threads:
        t.join()
    if errors:
        raise errors[0]
    if scheduler.pending and not scheduler.stopped:  # the deadline passed while workers waited
        print("run_matrix: stopped (deadline) before %d cell(s); rerun the same command to continue" %
              len(scheduler.pending), file=sys.stderr)
    return scheduler.stopped or bool(scheduler.pending)


def run_sequential(matrix, pending, results):
    """Runs the pending cells one after another; returns whether the matrix is incomplete."""
    for c in pending:
        start = time.monotonic()
        try:
            row = matrix.run_cell(c)
        except (Interrupted, KeyboardInterrupt):
            print("run_matrix: stopped (deadline or signal) during %s; rerun the same command to continue" % c["id"],
                  file=sys.stderr)
            return True
        results.add(c, row, start)
    return False


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog="See the module docstring (head -70 bench/run_matrix.py) for the config format.")
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
    p.add_argument("--gpus", type=parse_gpus, default=None, metavar="LIST",
                   help="run cells in parallel, one worker per listed device (e.g. 0,1,2,3): its atex commands get "
                        "CUDA_VISIBLE_DEVICES=<device> and OMP_NUM_THREADS=cpus/devices (unless set); every model "
                        "is still trained once; rows get a 'gpu' field. A worker running a cell holds "
                        "${TMPDIR:-/tmp}/atex_run_matrix_gpu<N>.lock (flock), so runs with overlapping lists take "
                        "turns on a GPU. Default: one cell after another, environment unchanged. "
                        "--dry-run and --list ignore it")
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
    rows = load_rows(os.path.join(args.out, "results.jsonl"))

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
    results = Results(args.out, rows)
    pending = []
    for c in selected:
        old = rows.get(c["id"])
        if old and (old.get("status") == "ok" or not args.retry_failed):
            results.counts["skipped"] += 1
            if args.dry_run:
                print("# %s: has a row (%s), skipped" % (c["id"], old.get("status")))
            continue
        if args.dry_run:
            print("# cell %s" % c["id"])
            matrix.run_cell(c)
            continue
        pending.append(c)
    if args.dry_run:
        return EXIT_COMPLETE
    if args.gpus:
        interrupted = run_parallel(matrix, pending, args.gpus, results)
    else:
        interrupted = run_sequential(matrix, pending, results)
    counts = results.counts
    if rows:
        write_csv(list(rows.values()), os.path.join(args.out, "results.csv"))
    print("run_matrix: %d ok, %d failed, %d skipped (had rows)%s; results in %s" %
          (counts["ok"], counts["failed"], counts["skipped"], ", INCOMPLETE" if interrupted else "", args.out))
    return EXIT_INCOMPLETE if interrupted else EXIT_COMPLETE


if __name__ == "__main__":
    sys.exit(main())
