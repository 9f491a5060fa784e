#!/usr/bin/env python3
"""Tests of bench/run_matrix.py and bench/paired_bootstrap.py (no GPU, no real atex):
--dry-run on every committed config, and a small matrix run against tests/bench/fake_atex.py
for resumability, failure rows, NaN/floor checks, --deadline + checkpoint resume, the CSV,
the paired bootstrap, and --gpus (parallel workers, shared models, the per-GPU lock files,
--deadline and SIGTERM with several workers).

    python3 tests/bench/test_run_matrix.py [--source-dir DIR] [--work-dir DIR] [unittest options]
"""
import argparse
import csv
import glob
import json
import os
import re
import shutil
import signal
import stat
import subprocess
import sys
import tempfile
import time
import unittest

SOURCE = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
WORK = None
PY = sys.executable


def environment(env):
    """os.environ with `env` applied; a None value removes the variable."""
    e = dict(os.environ)
    for k, v in (env or {}).items():
        if v is None:
            e.pop(k, None)
        else:
            e[k] = v
    return e


def run(*args, env=None, cwd=None):
    e = environment(env)
    p = subprocess.run([PY] + [str(a) for a in args], capture_output=True, text=True, env=e, cwd=cwd)
    return p.returncode, p.stdout, p.stderr


class Base(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp(prefix="run_matrix_", dir=WORK)
        self.log = os.path.join(self.dir, "fake.log")
        self.events_path = os.path.join(self.dir, "fake.events")
        self.atex = os.path.join(self.dir, "atex")
        with open(self.atex, "w") as f:  # an executable wrapper (committed files may lose their mode bits)
            f.write('#!/bin/sh\nexec "%s" "%s" "$@"\n' % (PY, os.path.join(SOURCE, "tests", "bench", "fake_atex.py")))
        os.chmod(self.atex, os.stat(self.atex).st_mode | stat.S_IXUSR)
        self.out = os.path.join(self.dir, "out")
        self.config = os.path.join(self.dir, "config.json")
        self.write_config()

    def tearDown(self):
        if not os.environ.get("KEEP_TEST_DIRS"):
            shutil.rmtree(self.dir, ignore_errors=True)

    def write_config(self, **changes):
        cfg = {
            "name": "fake",
            "datasets": {"scene": {"path": "${FAKE_DATA_ROOT:-data}/scene", "args": ["--timesteps", "3"]}},
            "seeds": [6666],
            "stage1": {"args": ["--set", "stage1.fine_iterations=10"]},
            "methods": {"none": {"stage2": False}, "uniform": {"textures": "uniform"},
                        "adaptive": {"textures": "adaptive", "set": ["stage2.ablations.anisotropic=true"]}},
            "budgets": ["full", {"name": "b50", "budget_of": "uniform", "fraction": 0.5, "args": ["--levers", "prune"]},
                        {"name": "k50", "keep_count": 0.5}],
            "fps": {"sizes": ["native", "1352x1014"], "repeats": 3},
            "backend": "cpu",
            "psnr_floor": 10,
        }
        cfg.update(changes)
        with open(self.config, "w") as f:
            json.dump(cfg, f)

    def matrix_env(self, env=None):
        # TMPDIR: the --gpus lock files of the tests stay in the test's folder (no clash with real runs).
        e = {"FAKE_ATEX_LOG": self.log, "FAKE_ATEX_EVENTS": self.events_path, "TMPDIR": self.dir}
        e.update(env or {})
        return e

    def matrix_argv(self, *extra, out=None):
        return [os.path.join(SOURCE, "bench", "run_matrix.py"), self.config, "--atex", self.atex,
                "--out", out or self.out] + [str(a) for a in extra]

    def matrix(self, *extra, env=None):
        return run(*self.matrix_argv(*extra), env=self.matrix_env(env))

    def rows(self, out=None):
        rows = {}
        with open(os.path.join(out or self.out, "results.jsonl")) as f:
            for line in f:
                r = json.loads(line)
                rows[r["cell"]] = r
        return rows

    def calls(self, prefix=None):
        if not os.path.exists(self.log):
            return []
        with open(self.log) as f:
            calls = [json.loads(l) for l in f]
        return [c for c in calls if prefix is None or c[0] == prefix]

    def stage1_running(self, out_name):
        """Whether a stage-1 train command of the run writing to `out_name` has started."""
        try:
            cmds = self.commands("train")
        except (ValueError, KeyError):  # the fake is writing a line right now
            return False
        return any(stage(c) == "1" and out_name in " ".join(c["args"]) for c in cmds)

    def commands(self, prefix=None):
        """The fake's invocations from its event file: {args, gpu, omp, init_exists, start, end (None:
        killed), rc}, in start order."""
        by_pid = {}
        if os.path.exists(self.events_path):
            with open(self.events_path) as f:
                for line in f:
                    e = json.loads(line)
                    if e["phase"] == "start":
                        by_pid[e["pid"]] = dict(e, start=e["time"], end=None, rc=None)
                    else:
                        by_pid[e["pid"]].update(end=e["time"], rc=e["rc"])
        cmds = sorted(by_pid.values(), key=lambda c: c["start"])
        return [c for c in cmds if prefix is None or c["args"][0] == prefix]


class DryRun(Base):
    def test_every_committed_config(self):
        configs = sorted(glob.glob(os.path.join(SOURCE, "bench", "configs", "*.json")))
        self.assertGreaterEqual(len(configs), 4)
        for config in configs:
            with self.subTest(config=os.path.basename(config)):
                out = os.path.join(self.dir, "dry")
                rc, stdout, stderr = run(os.path.join(SOURCE, "bench", "run_matrix.py"), config, "--dry-run",
                                         "--atex", "bg/bin/atex", "--out", out)
                self.assertEqual(rc, 0, stderr)
                rc2, listing, _ = run(os.path.join(SOURCE, "bench", "run_matrix.py"), config, "--list", "--out", out)
                self.assertEqual(rc2, 0)
                n = len(listing.strip().splitlines())
                self.assertGreater(n, 0)
                self.assertEqual(stdout.count("# cell "), n)
                self.assertIn("bg/bin/atex train", stdout)
                self.assertIn("--stage 1", stdout)
                self.assertIn(" eval ", stdout)
                self.assertIn(" fps ", stdout)
                # One stage-1 model per (dataset, variant, seed) that has cells, whatever the methods and
                # budgets ("only"/"skip" may leave a variant with fewer seeds).
                models = len({tuple(line.split()[0].split("/")[:3]) for line in listing.strip().splitlines()})
                self.assertEqual(stdout.count("--stage 1 "), models, config)
                self.assertFalse(os.path.exists(out), "a dry run must not write anything")

    def test_paper_config_shares_one_stage1_model_and_seed(self):
        rc, stdout, stderr = run(os.path.join(SOURCE, "bench", "run_matrix.py"),
                                 os.path.join(SOURCE, "bench", "configs", "panoptic_stage2.json"), "--dry-run",
                                 "--atex", "atex", "--out", os.path.join(self.dir, "p"))
        self.assertEqual(rc, 0, stderr)
        inits = set(re.findall(r"--init (\S+)", stdout))
        self.assertEqual(len(inits), 1, inits)
        self.assertEqual(set(re.findall(r"--seed (\d+)", stdout)), {"6666"})
        for variant in ("temporal_peak=false", "anisotropic=false", "visibility_normalization=false"):
            self.assertIn(variant, stdout)
        self.assertIn("--size 1352x1014", stdout)

    def test_only_and_bad_config(self):
        rc, stdout, _ = self.matrix("--dry-run", "--only", "adaptive/k50")
        self.assertEqual(rc, 0)
        self.assertEqual(stdout.count("# cell "), 1)
        self.assertIn("--keep-count 0.5", stdout)
        rc, stdout, _ = self.matrix("--dry-run", "--only", "uniform/full", "--stage1-time-limit", "300")
        self.assertEqual(rc, 0)
        self.assertEqual(stdout.count("--time-limit 300"), 1)
        self.assertRegex(stdout, r"--stage 1 .*--time-limit 300")
        self.write_config(methods={})
        rc, _, stderr = self.matrix()
        self.assertEqual(rc, 2)
        self.assertIn("methods", stderr)


class Matrix(Base):
    def test_runs_every_cell_then_resumes_without_running_anything(self):
        rc, stdout, stderr = self.matrix()
        self.assertEqual(rc, 0, stderr + stdout)
        rows = self.rows()
        self.assertEqual(len(rows), 9)
        self.assertTrue(all(r["status"] == "ok" for r in rows.values()), rows)
        self.assertEqual(len([c for c in self.calls("train") if "1" == c[c.index("--stage") + 1]]), 1)
        self.assertEqual(len([c for c in self.calls("train") if "2" == c[c.index("--stage") + 1]]), 2)
        self.assertEqual(len(self.calls("fit")), 6)
        for c in self.calls("train"):
            self.assertIn("--seed", c)
            self.assertEqual(c[c.index("--data") + 1], "data/scene")
            self.assertIn("--timesteps", c)
        # Every stage-2 run starts from the same stage-1 model.
        self.assertEqual(len({c[c.index("--init") + 1] for c in self.calls("train") if "--init" in c}), 1)
        r = rows["scene/full/s6666/adaptive/full"]
        # Without --gpus: no gpu field, and atex gets the harness's environment unchanged.
        self.assertNotIn("gpu", r)
        self.assertEqual({(c["gpu"], c["omp"]) for c in self.commands()},
                         {(os.environ.get("CUDA_VISIBLE_DEVICES"), os.environ.get("OMP_NUM_THREADS"))})
        self.assertAlmostEqual(r["psnr"], sum(v[2] for v in r["views"]) / len(r["views"]))
        self.assertEqual(len(r["views"]), 6)
        self.assertEqual(len(r["cameras"]), 2)
        self.assertEqual(r["histogram"]["4x4"], 25)
        self.assertEqual(r["train_s_stage1"], 60.0)
        self.assertEqual(r["train_s_stage2"], 20.0)
        self.assertEqual(r["model_bytes"], 8000)
        self.assertAlmostEqual(r["peak_gpu_gib"], 1.5)
        self.assertIn("fps_1352x1014", r)
        self.assertEqual(r["native_size"], "640x360")
        # b50: half of the UNIFORM model's size, for every method.
        for m in ("none", "uniform", "adaptive"):
            fit = [c for c in self.calls("fit") if "--budget" in c and "/%s.atex" % m in c[1].replace(os.sep, "/")
                   or ("--budget" in c and m == "none" and c[1].endswith("stage1.atex"))]
            self.assertTrue(fit, m)
            self.assertEqual(fit[0][fit[0].index("--budget") + 1], "6000")
            self.assertEqual(fit[0][fit[0].index("--levers") + 1], "prune", "the budget's own args")
        k50 = [c for c in self.calls("fit") if "--keep-count" in c]
        self.assertFalse([c for c in k50 if "--levers" in c], "one budget's args stay with its cells")
        self.assertTrue(all(c[c.index("--order-from") + 1].endswith("stage1.atex") for c in k50))
        with open(os.path.join(self.out, "results.csv")) as f:
            table = list(csv.DictReader(f))
        self.assertEqual(len(table), 9)
        for col in ("psnr", "ssim", "dssim1", "dssim2", "texture_mib", "model_mib", "gaussians", "hist_2x2",
                    "peak_gpu_gib", "train_s_stage1", "train_s_stage2", "fps_native", "fps_1352x1014", "psnr_cam0",
                    "dssim2_cam10", "dynamic_psnr", "dynamic_psnr_cam10"):
            self.assertIn(col, table[0])
        # The dynamic-region PSNR reaches the table from `atex eval --json` (the fake's: 4 dB under the PSNR).
        for r in table:
            if r["status"] == "ok":
                self.assertAlmostEqual(float(r["dynamic_psnr"]), float(r["psnr"]) - 4.0, places=4)

        calls = len(self.calls())
        rc, stdout, stderr = self.matrix()
        self.assertEqual(rc, 0, stderr)
        self.assertIn("9 skipped", stdout)
        self.assertEqual(len(self.calls()), calls, "a resumed matrix must not run anything")

    def test_train_split_adds_the_training_views_scores(self):
        self.write_config(eval={"train_split": True}, budgets=["full"])
        rc, stdout, stderr = self.matrix()
        self.assertEqual(rc, 0, stderr + stdout)
        rows = self.rows()
        self.assertEqual(len(rows), 3)
        for r in rows.values():
            self.assertAlmostEqual(r["train_psnr"], r["psnr"] + 1.5, msg=r["cell"])
        evals = self.calls("eval")
        self.assertEqual(len([c for c in evals if "--split" in c and c[c.index("--split") + 1] == "train"]), 3)
        self.assertEqual(len([c for c in evals if "--split" not in c]), 3)
        with open(os.path.join(self.out, "results.csv")) as f:
            self.assertIn("train_psnr", next(csv.reader(f)))
        self.write_config(eval={"train_split": "yes"})
        rc, _, stderr = self.matrix("--dry-run")
        self.assertEqual(rc, 2, stderr)
        self.assertIn("train_split", stderr)

    def test_growth_probes_collect_and_compare_with_the_same_seeds_uniform_row(self):
        self.write_config(budgets=["full"])
        rc, _, stderr = self.matrix()
        self.assertEqual(rc, 0, stderr)
        uniform = self.rows()["scene/full/s6666/uniform/full"]
        # A probe in the layout of bench/device/growth_probes.sh: every view 0.25 dB above uniform.
        probe_dir = os.path.join(self.dir, "probe2")
        os.makedirs(probe_dir)
        views = [{"camera": v[0], "timestep": v[1], "psnr": v[2] + 0.25} for v in uniform["views"]]
        files = {"train": {"seconds": {"textures": 1.0}, "test": {"mean": {"psnr": 0}, "views": views}},
                 "eval": {"mean": {"psnr": uniform["psnr"] + 0.25}, "views": views},
                 "evaltrain": {"mean": {"psnr": 30.0}, "views": views}}
        for suffix, content in files.items():
            with open(os.path.join(probe_dir, "s6666_early.%s.json" % suffix), "w") as f:
                json.dump(content, f)
        tool = os.path.join(SOURCE, "bench", "growth_probes.py")
        probes = os.path.join(self.dir, "probes.json")
        rc, _, stderr = run(tool, "collect", probe_dir, "--out", probes)
        self.assertEqual(rc, 0, stderr)
        with open(probes) as f:
            collected = json.load(f)["runs"]["probe2/s6666_early"]
        self.assertNotIn("views", collected["eval_train"])
        self.assertNotIn("views", collected["train"]["test"])
        self.assertEqual(len(collected["eval"]["views"]), len(views))
        rc, stdout, stderr = run(tool, "summary", probes, "--rows", os.path.join(self.out, "results.jsonl"),
                                 "--dataset", "scene", "--samples", "200")
        self.assertEqual(rc, 0, stderr)
        self.assertIn("| probe2/s6666_early |", stdout)
        self.assertIn("| 30.000 |", stdout)
        self.assertIn("+0.250 [+0.250, +0.250]", stdout)

    def test_budget_table_pairs_each_seed_with_its_own_baseline(self):
        # Values chosen so that a pairing across seeds, a wrong mean or a share of the wrong
        # unfitted model gives other figures; seed 7 lacks adaptive at b25 and a failed row is left out.
        rows = []
        for seed, offset in (("6666", 0.0), ("7", 1.0)):
            for method, psnr_full, gaussians_b25, psnr_b25 in (("uniform", 24.0, 100, 23.0),
                                                                ("adaptive", 24.1, 150, 23.5)):
                rows.append({"seed": seed, "method": method, "budget": "full", "status": "ok",
                             "psnr": psnr_full + offset, "model_mib": 100.0, "gaussians": 400 + 100 * offset,
                             "ssim": 0.8 + offset / 10, "dssim1": 0.1, "dssim2": ""})
                if not (seed == "7" and method == "adaptive"):
                    rows.append({"seed": seed, "method": method, "budget": "b25", "status": "ok",
                                 "psnr": psnr_b25 + 2 * offset, "model_mib": 25.0, "gaussians": gaussians_b25,
                                 "texels": 16 * gaussians_b25 * (1 + offset), "fit_s": 10 + 20 * offset})
        rows.append({"seed": "7", "method": "adaptive", "budget": "b25", "status": "failed", "psnr": 99.0,
                     "model_mib": 1.0, "gaussians": 1})
        path = os.path.join(self.dir, "budgets.csv")
        with open(path, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=["seed", "method", "budget", "status", "psnr", "model_mib", "gaussians",
                                              "ssim", "dssim1", "dssim2", "texels", "fit_s"])
            w.writeheader()
            w.writerows(rows)
        tool = os.path.join(SOURCE, "bench", "budget_table.py")
        rc, stdout, stderr = run(tool, path, "--budgets", "b25,full")
        self.assertEqual(rc, 0, stderr)
        lines = stdout.splitlines()
        # Uniform at b25: 23.0 (s6666) and 25.0 (s7); kept 100 of 400 and 100 of 500 Gaussians;
        # texels 1600 and 3200; fits of 10 and 30 s.
        b25_uniform = "| b25 | uniform | 24.000 | 23.000, 25.000 | - | - | - | 25.00 | 100 | 22.5 % | 2400 | 10.0-30.0 |"
        self.assertIn(b25_uniform, lines)
        # Adaptive at b25: seed 7's failed row is not a value.
        self.assertIn("| b25 | adaptive | 23.500 | 23.500, - | - | - | - | 25.00 | 150 | 37.5 % | 2400 | 10.0-10.0 |",
                      lines)
        # SSIM/DSSIM: means where every seed has a value, "-" where one is missing.
        full_uniform = "| full | uniform | 24.500 | 24.000, 25.000 | 0.8500 | 0.1000 | - | 100.00 | 450 | 100.0 % | - | - |"
        self.assertIn(full_uniform, lines)
        self.assertLess(lines.index(b25_uniform), lines.index(full_uniform), "budgets in the order asked for")
        # Adaptive - uniform: only seed 6666 has both at b25; at full each seed has its own pair.
        self.assertIn("| b25 | +0.500, - | +0.500 | 1 |", lines)
        self.assertIn("| full | +0.100, +0.100 | +0.100 | 2 |", lines)
        rc, _, stderr = run(tool, os.path.join(self.dir, "missing.csv"))
        self.assertEqual(rc, 2)
        self.assertIn("missing.csv", stderr)

    def test_budget_table_never_averages_two_variants(self):
        fields = ["variant", "seed", "method", "budget", "status", "psnr", "model_mib", "gaussians"]
        path = os.path.join(self.dir, "variants.csv")
        with open(path, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=fields)
            w.writeheader()
            for variant, psnr in (("base", 28.0), ("late", 27.0)):
                w.writerow({"variant": variant, "seed": "1", "method": "none", "budget": "full", "status": "ok",
                            "psnr": psnr, "model_mib": 70.0, "gaussians": 100})
        tool = os.path.join(SOURCE, "bench", "budget_table.py")
        rc, _, stderr = run(tool, path)
        self.assertEqual(rc, 2)
        self.assertIn("variants base, late", stderr)
        rc, stdout, stderr = run(tool, path, "--variant", "late")
        self.assertEqual(rc, 0, stderr)
        self.assertIn("| full | none | 27.000 | 27.000 |", stdout)
        rc, _, stderr = run(tool, path, "--variant", "nope")
        self.assertEqual(rc, 2)
        self.assertIn("no rows of variant 'nope'", stderr)

    def test_failures_become_rows_and_retry_failed_reruns_them(self):
        rc, stdout, stderr = self.matrix(env={"FAKE_ATEX_FAIL": "--textures adaptive"})
        self.assertEqual(rc, 0, stderr)
        rows = self.rows()
        self.assertEqual(len(rows), 9)
        failed = {k for k, r in rows.items() if r["status"] == "failed"}
        self.assertEqual(failed, {"scene/full/s6666/adaptive/%s" % b for b in ("full", "b50", "k50")})
        r = rows["scene/full/s6666/adaptive/b50"]
        self.assertEqual(r["failed_step"], "train adaptive")
        self.assertIn("injected failure", r["cause"])
        # The failing training ran once, not once per cell.
        self.assertEqual(len([c for c in self.calls("train") if "adaptive" in c]), 1)
        rc, stdout, _ = self.matrix()
        self.assertIn("9 skipped", stdout)
        rc, stdout, stderr = self.matrix("--retry-failed")
        self.assertEqual(rc, 0, stderr)
        self.assertTrue(all(r["status"] == "ok" for r in self.rows().values()))

    def test_stage1_failure_fails_every_cell_with_its_cause(self):
        rc, _, stderr = self.matrix(env={"FAKE_ATEX_FAIL": "--stage 1"})
        self.assertEqual(rc, 0, stderr)
        rows = self.rows()
        self.assertTrue(all(r["status"] == "failed" and r["failed_step"] == "train stage1" for r in rows.values()))
        self.assertEqual(len(self.calls("train")), 1)

    def test_nan_metric_and_psnr_floor(self):
        rc, _, stderr = self.matrix("--only", "/full$", env={"FAKE_ATEX_NAN": "uniform.atex"})
        self.assertEqual(rc, 0, stderr)
        rows = self.rows()
        self.assertEqual(rows["scene/full/s6666/uniform/full"]["status"], "failed")
        self.assertIn("psnr", rows["scene/full/s6666/uniform/full"]["cause"])
        self.assertEqual(rows["scene/full/s6666/none/full"]["status"], "ok")
        self.write_config(psnr_floor=25.5)
        shutil.rmtree(self.out)
        rc, _, _ = self.matrix("--only", "/full$")
        rows = self.rows()
        self.assertEqual(rows["scene/full/s6666/none/full"]["status"], "failed")
        self.assertIn("below the floor", rows["scene/full/s6666/none/full"]["cause"])
        self.assertEqual(rows["scene/full/s6666/adaptive/full"]["status"], "ok")

    def test_deadline_interrupts_and_the_rerun_resumes_from_the_checkpoint(self):
        rc, stdout, stderr = self.matrix("--deadline", "1.5", env={"FAKE_ATEX_SLEEP": "--stage 1:30"})
        self.assertEqual(rc, 3, stdout + stderr)
        self.assertIn("rerun", stderr)
        self.assertFalse(os.path.exists(os.path.join(self.out, "results.jsonl")))
        rc, stdout, stderr = self.matrix()
        self.assertEqual(rc, 0, stderr)
        s1 = [c for c in self.calls("train") if c[c.index("--stage") + 1] == "1"]
        self.assertEqual(len(s1), 2)
        self.assertIn("--resume", s1[1])
        row = self.rows()["scene/full/s6666/none/full"]
        self.assertEqual(row["status"], "ok")
        self.assertEqual(row["train_resumes_stage1"], 1)
        self.assertGreater(row["train_wall_s_stage1"], 1.0)  # the interrupted attempt is counted

    def test_command_timeout_is_a_failure_row(self):
        self.write_config(command_timeout=1)
        rc, _, stderr = self.matrix("--only", "none/full", env={"FAKE_ATEX_SLEEP": "^fps:5"})
        self.assertEqual(rc, 0, stderr)
        row = self.rows()["scene/full/s6666/none/full"]
        self.assertEqual(row["status"], "failed")
        self.assertIn("timed out", row["cause"])

    def test_paired_bootstrap(self):
        rc, _, stderr = self.matrix()
        self.assertEqual(rc, 0, stderr)
        out_json = os.path.join(self.dir, "ci.json")
        args = (os.path.join(SOURCE, "bench", "paired_bootstrap.py"), os.path.join(self.out, "results.jsonl"),
                "--baseline", "uniform", "--method", "adaptive", "--samples", "2000", "--json", out_json)
        rc, stdout, stderr = run(*args)
        self.assertEqual(rc, 0, stderr)
        self.assertIn("adaptive - uniform", stdout)
        with open(out_json) as f:
            res = json.load(f)
        full = [r for r in res if r["budget"] == "full"][0]
        self.assertEqual(full["pairs"], 6)
        self.assertAlmostEqual(full["mean"], 0.2 + 0.03 * 2 / 6)  # the fake's adaptive - uniform
        self.assertLessEqual(full["ci95"][0], full["mean"])
        self.assertGreaterEqual(full["ci95"][1], full["mean"])
        self.assertGreater(full["ci95"][0], 0)
        rc, stdout2, _ = run(*args)
        self.assertEqual(stdout, stdout2, "the bootstrap is seeded")
        rc, stdout, _ = run(args[0], args[1], "--baseline", "uniform", "--unit", "camera", "--samples", "500")
        self.assertEqual(rc, 0)
        self.assertIn("(camera)", stdout)
        # One seed resampled as a whole: one cluster, so no interval and no P (not a zero-width one).
        rc, stdout, _ = run(args[0], args[1], "--baseline", "uniform", "--method", "adaptive", "--unit", "seed",
                            "--json", out_json)
        self.assertEqual(rc, 0)
        self.assertIn("| 1 (seed) |", stdout)
        self.assertIn("| none (one cluster) | - |", stdout)
        with open(out_json) as f:
            one = [r for r in json.load(f) if r["budget"] == "full"][0]
        self.assertIsNone(one["ci95"])
        self.assertIsNone(one["p_le_0"])

    def test_paired_bootstrap_pools_seeds_pairing_each_with_its_own_baseline(self):
        self.write_config(seeds=[6666, 7], budgets=["full"])
        rc, _, stderr = self.matrix()
        self.assertEqual(rc, 0, stderr)
        out_json = os.path.join(self.dir, "ci.json")
        rc, stdout, stderr = run(os.path.join(SOURCE, "bench", "paired_bootstrap.py"),
                                 os.path.join(self.out, "results.jsonl"), "--baseline", "uniform", "--method",
                                 "adaptive", "--unit", "seed", "--samples", "500", "--json", out_json)
        self.assertEqual(rc, 0, stderr)
        self.assertIn("(seed)", stdout)
        with open(out_json) as f:
            res = json.load(f)
        self.assertEqual(len(res), 1)
        self.assertEqual(res[0]["seed"], "6666,7")
        self.assertEqual(res[0]["clusters"], 2)
        self.assertEqual(res[0]["pairs"], 12)  # 6 views x 2 seeds; a pairing across seeds would give 24
        self.assertAlmostEqual(res[0]["mean"], 0.2 + 0.03 * 2 / 6)


def stage(cmd):
    return cmd["args"][cmd["args"].index("--stage") + 1]


def overlap(a, b):
    """Whether two finished commands ran at the same time (by the fake's wall-clock stamps)."""
    return max(a["start"], b["start"]) < min(a["end"], b["end"])


def alive(pid):
    """Whether a process exists and is not a zombie (a killed fake may wait to be reaped by init)."""
    try:
        with open("/proc/%d/stat" % pid) as f:
            return f.read().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except FileNotFoundError:
        return False
    except OSError:  # no /proc: ask the kernel
        try:
            os.kill(pid, 0)
            return True
        except ProcessLookupError:
            return False


class Gpus(Base):
    """--gpus: one worker per device; 2 variants x 2 methods = 2 independent stage-1 models, each
    needed by 2 cells (none: the stage-1 model itself; uniform: its stage 2 from it)."""
    CELLS = ["scene/%s/s6666/%s/full" % (v, m) for v in ("va", "vb") for m in ("none", "uniform")]

    def setUp(self):
        super().setUp()
        self.write_gpu_config()

    def write_gpu_config(self, budgets=("full",)):
        self.write_config(variants={"va": {"args": ["--timestep-stride", "1"]},
                                    "vb": {"args": ["--timestep-stride", "2"]}},
                          methods={"none": {"stage2": False}, "uniform": {"textures": "uniform"}},
                          budgets=list(budgets), fps={"sizes": ["native"], "repeats": 3})

    def with_b50(self):
        """b50 cells need the uniform model too: each stage-2 model is then shared by 3 cells
        (uniform/full, none/b50, uniform/b50) that two workers could take at the same time."""
        self.write_gpu_config(["full", {"name": "b50", "budget_of": "uniform", "fraction": 0.5}])
        return self.CELLS + [c.replace("/full", "/b50") for c in self.CELLS]

    def assert_no_overlap_per_gpu(self, cmds):
        for gpu in {c["gpu"] for c in cmds}:
            on_gpu = [c for c in cmds if c["gpu"] == gpu and c["end"] is not None]
            for a, b in zip(on_gpu, on_gpu[1:]):
                self.assertGreaterEqual(b["start"], a["end"], "two commands at once on GPU %s: %s / %s" %
                                        (gpu, a["args"][:2], b["args"][:2]))

    def test_models_are_trained_once_and_every_gpu_is_used(self):
        cells = self.with_b50()
        rc, stdout, stderr = self.matrix("--gpus", "0,1",
                                         env={"FAKE_ATEX_SLEEP": "^train:0.3", "OMP_NUM_THREADS": None})
        self.assertEqual(rc, 0, stdout + stderr)
        rows = self.rows()
        self.assertEqual(sorted(rows), sorted(cells))
        self.assertTrue(all(r["status"] == "ok" for r in rows.values()), rows)
        self.assertEqual({r["gpu"] for r in rows.values()}, {"0", "1"})
        self.assertEqual(stdout.count("[gpu "), 8, stdout)
        cmds = self.commands()
        self.assertTrue(all(c["end"] is not None and c["rc"] == 0 for c in cmds))
        self.assertEqual({c["gpu"] for c in cmds}, {"0", "1"})
        self.assertEqual({c["omp"] for c in cmds}, {str(max(1, os.cpu_count() // 2))})
        trains = self.commands("train")
        s1 = {c["args"][c["args"].index("--out") + 1]: c for c in trains if stage(c) == "1"}
        self.assertEqual(len([c for c in trains if stage(c) == "1"]), 2, "each stage-1 model trained once")
        self.assertEqual(len(s1), 2, "one stage-1 model per variant")
        s2 = [c for c in trains if stage(c) == "2"]
        self.assertEqual(len(s2), 2, "each stage-2 model trained once")
        for c in s2:  # started from its own variant's stage-1 model, after that model was written
            init = c["args"][c["args"].index("--init") + 1]
            self.assertIn(init, s1)
            self.assertTrue(c["init_exists"])
            self.assertGreaterEqual(c["start"], s1[init]["end"])
        self.assert_no_overlap_per_gpu(cmds)
        with open(os.path.join(self.out, "results.csv")) as f:
            self.assertEqual({r["gpu"] for r in csv.DictReader(f)}, {"0", "1"})

    def test_a_failed_model_fails_its_cells_and_is_trained_once(self):
        cells = self.with_b50()
        rc, stdout, stderr = self.matrix("--gpus", "0,1", env={"FAKE_ATEX_FAIL": "--textures uniform"})
        self.assertEqual(rc, 0, stdout + stderr)
        rows = self.rows()
        self.assertEqual(sorted(rows), sorted(cells))
        for cell, r in rows.items():
            self.assertEqual(r["status"], "ok" if cell.endswith("none/full") else "failed", cell)
            if r["status"] == "failed":
                self.assertEqual(r["failed_step"], "train uniform")
        self.assertEqual(len([c for c in self.calls("train") if "uniform" in c]), 2, "once per variant")

    def test_cells_run_in_parallel(self):
        # Overlap of the recorded start/end times rather than wall time: robust on a loaded machine.
        rc, stdout, stderr = self.matrix("--gpus", "0,1", env={"FAKE_ATEX_SLEEP": "^train:0.8"})
        self.assertEqual(rc, 0, stdout + stderr)
        trains = self.commands("train")
        self.assertEqual(len(trains), 4)
        self.assertTrue(any(overlap(a, b) for a in trains for b in trains if a["gpu"] != b["gpu"]),
                        "no two trainings ran at once on the two GPUs")
        self.assert_no_overlap_per_gpu(self.commands())

    def test_two_processes_take_turns_on_a_gpu(self):
        self.write_config(methods={"none": {"stage2": False}, "uniform": {"textures": "uniform"}},
                          budgets=["full"], fps={"sizes": ["native"], "repeats": 3})
        outs = [os.path.join(self.dir, "out%d" % i) for i in (1, 2)]
        env = environment(self.matrix_env({"FAKE_ATEX_SLEEP": "^train:0.3"}))
        procs = [subprocess.Popen([PY] + self.matrix_argv("--gpus", "0", out=o), env=env, stdout=subprocess.PIPE,
                                  stderr=subprocess.STDOUT, text=True) for o in outs]
        for p in procs:
            output = p.communicate(timeout=60)[0]
            self.assertEqual(p.returncode, 0, output)
        for o in outs:
            self.assertEqual(len(self.rows(o)), 2)
        cmds = self.commands()
        self.assertEqual(len(cmds), 2 * 2 * 4)  # 2 processes x (2 trainings + 2 x (eval, info, fps))
        self.assertEqual({c["gpu"] for c in cmds}, {"0"})
        for a, b in zip(cmds, cmds[1:]):
            self.assertGreaterEqual(b["start"], a["end"], "two processes ran commands on GPU 0 at once")
        self.assertTrue(os.path.exists(os.path.join(self.dir, "atex_run_matrix_gpu0.lock")))

    def test_a_waiting_worker_leaves_its_gpu_to_another_process(self):
        # Process A (--gpus 0,1): both cells need one stage-1 model, so the worker that does not train it
        # waits. Process B (another config) on that worker's GPU must get it meanwhile, not after A's stage 1.
        self.write_config(methods={"none": {"stage2": False}, "uniform": {"textures": "uniform"}},
                          budgets=["full"], fps={"sizes": ["native"], "repeats": 3})
        env = environment(self.matrix_env({"FAKE_ATEX_SLEEP": "--stage 1:6"}))
        a = subprocess.Popen([PY] + self.matrix_argv("--gpus", "0,1", out=os.path.join(self.dir, "outA")), env=env,
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        # B starts once A's stage 1 runs (GPU 0 trains, GPU 1 waits), not after a fixed delay, and
        # that stage 1 lasts long enough for B to start a command on a loaded machine (CTest -j).
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and not self.stage1_running("outA"):
            time.sleep(0.05)
        # Either of A's workers may take the stage-1 cell (a thread race): B goes to the other GPU.
        a_gpu = [c["gpu"] for c in self.commands("train") if stage(c) == "1" and "outA" in " ".join(c["args"])]
        self.assertEqual(len(a_gpu), 1)
        waiting_gpu = "1" if a_gpu[0] == "0" else "0"
        b = subprocess.Popen([PY] + self.matrix_argv("--gpus", waiting_gpu, out=os.path.join(self.dir, "outB")),
                             env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        for p in (a, b):
            output = p.communicate(timeout=60)[0]
            self.assertEqual(p.returncode, 0, output)
        cmds = self.commands()
        a_stage1 = [c for c in cmds if c["args"][0] == "train" and stage(c) == "1" and "outA" in " ".join(c["args"])]
        b_cmds = [c for c in cmds if "outB" in " ".join(c["args"])]
        self.assertEqual(len(a_stage1), 1)
        self.assertTrue(b_cmds)
        self.assertTrue(any(overlap(a_stage1[0], c) for c in b_cmds),
                        "process B waited for process A's stage 1 although A's GPU-1 worker had no cell")
        self.assert_no_overlap_per_gpu(cmds)

    def test_deadline_stops_every_worker_and_the_rerun_completes(self):
        start = time.monotonic()
        rc, stdout, stderr = self.matrix("--gpus", "0,1", "--deadline", "1.5",
                                         env={"FAKE_ATEX_SLEEP": "--stage 1:30", "OMP_NUM_THREADS": "3"})
        self.assertEqual(rc, 3, stdout + stderr)
        self.assertLess(time.monotonic() - start, 20)
        self.assertIn("rerun", stderr)
        self.assertIn("INCOMPLETE", stdout)
        self.assertFalse(os.path.exists(os.path.join(self.out, "results.jsonl")))
        killed = self.commands("train")
        self.assertEqual(len(killed), 2)
        self.assertEqual({c["gpu"] for c in killed}, {"0", "1"})
        self.assertEqual({c["omp"] for c in killed}, {"3"}, "a set OMP_NUM_THREADS is kept")
        self.assertTrue(all(c["end"] is None and not alive(c["pid"]) for c in killed))
        rc, stdout, stderr = self.matrix("--gpus", "0,1")
        self.assertEqual(rc, 0, stdout + stderr)
        rows = self.rows()
        self.assertEqual(sorted(rows), sorted(self.CELLS))
        self.assertTrue(all(r["status"] == "ok" for r in rows.values()), rows)
        s1 = [c for c in self.commands("train") if stage(c) == "1"]
        self.assertEqual(len(s1), 4)
        self.assertTrue(all("--resume" in c["args"] for c in s1[2:]))
        self.assertTrue(all(r["train_resumes_stage1"] == 1 for r in rows.values()))

    def test_sigterm_stops_every_worker(self):
        env = environment(self.matrix_env({"FAKE_ATEX_SLEEP": "--stage 1:30"}))
        p = subprocess.Popen([PY] + self.matrix_argv("--gpus", "0,1"), env=env, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
        try:
            give_up = time.monotonic() + 20
            while len(self.commands("train")) < 2 and time.monotonic() < give_up and p.poll() is None:
                time.sleep(0.05)
            self.assertEqual(len(self.commands("train")), 2, "both stage-1 trainings should have started")
            p.send_signal(signal.SIGTERM)
            sent = time.monotonic()
            stdout, stderr = p.communicate(timeout=30)
            # Terminated at once, not after the 10 s grace that ends in SIGKILL (nor the 30 s sleep).
            self.assertLess(time.monotonic() - sent, 8)
        finally:
            if p.poll() is None:
                p.kill()
                p.communicate()
        self.assertEqual(p.returncode, 3, stdout + stderr)
        self.assertIn("rerun", stderr)
        self.assertFalse(os.path.exists(os.path.join(self.out, "results.jsonl")))
        self.assertTrue(all(c["end"] is None and not alive(c["pid"]) for c in self.commands("train")))
        for variant in ("va", "vb"):
            with open(os.path.join(self.out, "models", "scene", variant, "s6666", "stage1.attempts.json")) as f:
                self.assertEqual([a["result"] for a in json.load(f)], ["interrupted"])

    def test_bad_gpus_is_a_usage_error_and_dry_run_ignores_gpus(self):
        for bad in ("", "a", "0,0", "-1", "0,,1", "1.5"):
            rc, _, stderr = self.matrix("--gpus=" + bad)
            self.assertEqual(rc, 2, "--gpus=%r: %s" % (bad, stderr))
            self.assertIn("--gpus", stderr)
        self.assertEqual(self.calls(), [])
        _, plain, _ = self.matrix("--dry-run")
        rc, with_gpus, stderr = self.matrix("--dry-run", "--gpus", "0,1")
        self.assertEqual(rc, 0, stderr)
        self.assertEqual(with_gpus, plain)
        rc, listing, _ = self.matrix("--list", "--gpus", "0,1")
        self.assertEqual((rc, len(listing.splitlines())), (0, 4))


if __name__ == "__main__":
    parser = argparse.ArgumentParser(add_help=False)
    parser.add_argument("--source-dir", default=SOURCE)
    parser.add_argument("--work-dir", default=None)
    known, rest = parser.parse_known_args()
    SOURCE = os.path.abspath(known.source_dir)
    if known.work_dir:
        os.makedirs(known.work_dir, exist_ok=True)
        WORK = known.work_dir
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)
