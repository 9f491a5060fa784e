"""atex.fit, atex.train and atex.convert, with their progress callbacks and cancellation."""

import os
import pathlib
import subprocess

import numpy as np
import pytest

import atex
from conftest import SAMPLE, require_data

FAST = dict(probes=2, probe_size=48, backend="cpu")


@pytest.fixture(scope="module")
def two_fits(sample):
    """One plan for two budgets (fits take a while on the CPU), with the progress calls it made."""
    seen = []
    results = atex.fit(sample, budget=[1 << 20, "1.5MiB"], progress=seen.append, **FAST)
    return results, seen


def test_fit_meets_the_budget(sample, two_fits):
    budget = 1 << 20
    fitted, report = two_fits[0][0]
    assert isinstance(fitted, atex.Asset)
    assert report["bytes"] <= budget and report["budget_bytes"] == budget
    assert len(fitted.to_bytes()) == report["bytes"]  # the fitted asset is exactly what the report sizes
    assert fitted.gaussian_count <= sample.gaussian_count
    assert report["gaussians"]["after"] == fitted.gaussian_count
    assert report["moves"]
    assert np.isfinite(fitted.gaussians.positions).all()


def test_fit_several_budgets_share_a_plan(two_fits):
    results = two_fits[0]
    assert len(results) == 2
    (small, r_small), (large, r_large) = results
    assert r_small["bytes"] <= 1 << 20 < r_large["bytes"] <= 1536 * 1024
    assert small.gaussian_count <= large.gaussian_count


def test_fit_reports_progress(two_fits):
    seen = two_fits[1]
    assert seen and {"move", "bytes", "target_bytes", "text"} <= set(seen[0])
    assert [p["move"] for p in seen] == list(range(1, len(seen) + 1))


def test_fit_below_the_floor_raises_budget_too_small(sample):
    with pytest.raises(atex.Error) as e:
        atex.fit(sample, budget=1000, **FAST)
    assert e.value.name == "budget-too-small" and e.value.code == 16


def test_fit_cancellation(sample):
    class Stop(Exception):
        pass

    calls = []

    def stop(progress):
        calls.append(progress)
        raise Stop()

    with pytest.raises(Stop):
        atex.fit(sample, budget="1MiB", progress=stop, **FAST)
    assert len(calls) == 1  # stopped after the first move
    with pytest.raises(atex.Error) as e:
        atex.fit(sample, budget="1MiB", progress=lambda p: False, **FAST)
    assert e.value.name == "cancelled"


def test_fit_writes_what_atex_fit_writes(sample, two_fits, tmp_path):
    """atex.fit runs the CLI's fit (RunFit): the same options give the same files, byte for byte."""
    cli = pathlib.Path(os.environ.get("ATEX_BINARY_DIR", "/nonexistent")) / "bin" / "atex"
    if not cli.exists():
        pytest.skip(f"no atex CLI at {cli} (ATEX_BINARY_DIR)")
    out = tmp_path / "fit_{}.atex"
    subprocess.run([str(cli), "fit", str(SAMPLE), str(out), "--budget", "1048576,1.5MiB", "--probes", "2",
                    "--probe-size", "48", "--backend", "cpu", "--json"], check=True, stdout=subprocess.DEVNULL)
    written = sorted(tmp_path.glob("fit_*.atex"), key=lambda p: p.stat().st_size)
    assert [p.read_bytes() for p in written] == [fitted.to_bytes() for fitted, _ in two_fits[0]]


def test_fit_without_a_budget_keeps_a_fraction_of_the_gaussians(sample):
    fitted, report = atex.fit(sample, keep_count=0.5, **FAST)
    assert report["budget_bytes"] == 0 and report["keep_count"]["fraction"] == 0.5
    assert fitted.gaussian_count == report["keep_count"]["kept"] == report["gaussians"]["after"]
    assert abs(fitted.gaussian_count - sample.gaussian_count / 2) <= 1
    assert report["moves"] == [] and "estimated_psnr_vs_input" not in report  # no plan was built


def test_fit_options_are_checked_before_any_work(sample):
    with pytest.raises(atex.Error, match="budget=, quality= or keep_count="):
        atex.fit(sample, **FAST)
    with pytest.raises(atex.Error, match="need --data"):
        atex.fit(sample, quality=30.0, **FAST)
    for bad in (dict(step_growth=0.5), dict(min_texture_step=2.0), dict(keep_count=1.5)):
        with pytest.raises(atex.Error) as e:
            atex.fit(sample, budget="1MiB", **bad, **FAST)
        assert e.value.name == "invalid-argument", bad


def test_fit_with_a_dataset_reports_test_metrics(sample, lego):
    fitted, report = atex.fit(sample, budget="1.5MiB", dataset=lego, eval_views=2, **FAST)
    assert report["bytes"] <= 1536 * 1024
    assert report["test"]["views"] == 2 and report["input_test"]["views"] == 2
    assert 10 < report["test"]["psnr"] <= report["input_test"]["psnr"] + 0.5


def test_fit_help_says_what_the_header_says():
    doc = atex.fit.__doc__
    assert "budget" in doc and "budget-too-small" in doc and "at most the budget" in doc


def tiny_config():
    return {
        "stage1": {"coarse_iterations": 6, "fine_iterations": 6, "batch_size": 1, "init_points": 500,
                   "densify": {"enabled": False}},
        "stage2": {"iterations": 4, "batch_size": 1, "growth_steps": [2]},
        "eval_every": 0, "eval_views": 2, "checkpoint_every": 0,
    }


def test_train_calls_progress_and_returns_an_asset():
    data = str(require_data("dnerf_lego_tiny/tiny_dnerf_data.npz"))
    seen = []
    asset, summary = atex.train(data, tiny_config(), progress=seen.append, backend="cpu")
    assert asset.gaussian_count > 0 and asset.textures is not None and asset.deformation is not None
    assert summary["steps"] == {"coarse": 6, "fine": 6, "textures": 4}
    phases = {p["phase"] for p in seen}
    assert {"coarse", "fine"} <= phases


def test_train_stops_on_an_exception_in_progress():
    data = str(require_data("dnerf_lego_tiny/tiny_dnerf_data.npz"))
    calls = []

    def interrupt(progress):
        calls.append(progress)
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        atex.train(data, tiny_config(), progress=interrupt, backend="cpu")
    assert len(calls) == 1  # training stopped at the first call


def test_train_rejects_an_unknown_config_key():
    data = str(require_data("dnerf_lego_tiny/tiny_dnerf_data.npz"))
    with pytest.raises(atex.Error) as e:
        atex.train(data, {"stage1": {"no_such_key": 1}}, backend="cpu")
    assert "no_such_key" in e.value.message


def test_convert_to_ply_and_back(sample, tmp_path):
    out = tmp_path / "lego.ply"
    report = atex.convert(str(__import__("conftest").SAMPLE), str(out), time=0.5)
    assert report["gaussians"] == sample.gaussian_count
    assert report["dropped"]  # textures and deformation do not fit in a PLY
    back = atex.read(str(out))
    assert back.gaussian_count == sample.gaussian_count
    # The sample's world is +z up (metadata "up"); a 3DGS PLY is -y up, so convert turns the world:
    # (x, y, z) -> (x, -z, y).
    p = sample.deform(0.5).positions
    expected = np.stack([p[:, 0], -p[:, 2], p[:, 1]], axis=1)
    np.testing.assert_allclose(back.gaussians.positions, expected, atol=1e-5)


def test_convert_errors_raise(tmp_path):
    with pytest.raises(atex.Error) as e:
        atex.convert(str(tmp_path / "missing.ply"), str(tmp_path / "x.atex"))
    assert e.value.code != 0


def test_ctrl_c_stops_training_without_a_callback():
    import _thread
    import threading
    import time

    data = str(require_data("dnerf_lego_tiny/tiny_dnerf_data.npz"))
    config = tiny_config()
    config["stage1"]["coarse_iterations"] = 1000000  # hours: only the interrupt can end it
    timer = threading.Timer(1.0, _thread.interrupt_main)  # as Ctrl-C: SIGINT's flag for the main thread
    timer.start()
    start = time.monotonic()
    try:
        with pytest.raises(KeyboardInterrupt):
            atex.train(data, config, backend="cpu")
    finally:
        timer.cancel()
    assert time.monotonic() - start < 120
