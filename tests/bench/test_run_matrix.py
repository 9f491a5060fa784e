#!/usr/bin/env python3
"""Tests of bench/run_matrix.py and bench/paired_bootstrap.py (no GPU, no real atex):
--dry-run on every committed config, and a small matrix run against tests/bench/fake_atex.py
for resumability, failure rows, NaN/floor checks, --deadline + checkpoint resume, the CSV and
the paired bootstrap.

    python3 tests/bench/test_run_matrix.py [--source-dir DIR] [--work-dir DIR] [unittest options]
"""
import argparse
import csv
import glob
import json
import os
import re
import shutil
import stat
import subprocess
import sys
import tempfile
import unittest

SOURCE = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
WORK = None
PY = sys.executable


def run(*args, env=None, cwd=None):
    e = dict(os.environ)
    e.update(env or {})
    p = subprocess.run([PY] + [str(a) for a in args], capture_output=True, text=True, env=e, cwd=cwd)
    return p.returncode, p.stdout, p.stderr


class Base(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp(prefix="run_matrix_", dir=WORK)
        self.log = os.path.join(self.dir, "fake.log")
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
            "budgets": ["full", {"name": "b50", "budget_of": "uniform", "fraction": 0.5},
                        {"name": "k50", "keep_count": 0.5}],
            "fps": {"sizes": ["native", "1352x1014"], "repeats": 3},
            "backend": "cpu",
            "psnr_floor": 10,
        }
        cfg.update(changes)
        with open(self.config, "w") as f:
            json.dump(cfg, f)

    def matrix(self, *extra, env=None):
        e = {"FAKE_ATEX_LOG": self.log}
        e.update(env or {})
        return run(os.path.join(SOURCE, "bench", "run_matrix.py"), self.config, "--atex", self.atex, "--out", self.out,
                   *extra, env=e)

    def rows(self):
        rows = {}
        with open(os.path.join(self.out, "results.jsonl")) as f:
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
                self.assertEqual(stdout.count("--stage 1 "), 1 if "stress" not in config else 7, config)
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
        k50 = [c for c in self.calls("fit") if "--keep-count" in c]
        self.assertTrue(all(c[c.index("--order-from") + 1].endswith("stage1.atex") for c in k50))
        with open(os.path.join(self.out, "results.csv")) as f:
            table = list(csv.DictReader(f))
        self.assertEqual(len(table), 9)
        for col in ("psnr", "ssim", "dssim1", "dssim2", "texture_mib", "model_mib", "gaussians", "hist_2x2",
                    "peak_gpu_gib", "train_s_stage1", "train_s_stage2", "fps_native", "fps_1352x1014", "psnr_cam0",
                    "dssim2_cam10"):
            self.assertIn(col, table[0])

        calls = len(self.calls())
        rc, stdout, stderr = self.matrix()
        self.assertEqual(rc, 0, stderr)
        self.assertIn("9 skipped", stdout)
        self.assertEqual(len(self.calls()), calls, "a resumed matrix must not run anything")

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
