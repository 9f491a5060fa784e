"""atex.render, atex.eval, atex.Dataset and atex.Tensor (DLPack on the host)."""

import json
import os
import subprocess

import numpy as np
import pytest

import atex
from conftest import SAMPLE, SOURCE_DIR


def cli():
    path = os.path.join(os.environ.get("ATEX_BINARY_DIR", str(SOURCE_DIR / "build")), "bin", "atex")
    if not os.path.exists(path):
        pytest.skip(f"no atex binary at {path}")
    return path


def test_render_orbit_view(sample):
    camera = atex.orbit_camera(sample, width=64, height=48)
    image = atex.render(sample, camera, t=0.0, backend="cpu")
    assert image.shape == (48, 64, 3) and image.dtype == np.float32
    assert np.isfinite(image).all()
    assert image.std() > 0.01  # something is in view, not a flat background
    later = atex.render(sample, camera, t=sample.time_range[1], backend="cpu")
    assert not np.array_equal(image, later)  # the scene moves
    again = atex.render(sample, camera, t=0.0, backend="cpu")
    np.testing.assert_array_equal(image, again)


def test_render_camera_time_is_the_default(sample):
    camera = atex.orbit_camera(sample, width=32, height=24, t=sample.time_range[1])
    a = atex.render(sample, camera, backend="cpu")
    b = atex.render(sample, camera, t=sample.time_range[1], backend="cpu")
    np.testing.assert_array_equal(a, b)


def test_render_into_a_tensor_shares_memory_through_dlpack(sample):
    camera = atex.orbit_camera(sample, width=40, height=30)
    tensor = atex.render(sample, camera, backend="cpu", output="tensor")
    assert isinstance(tensor, atex.Tensor)
    assert tensor.shape == (30, 40, 3) and tensor.device == "cpu"
    assert tensor.__dlpack_device__() == (1, 0)
    via_dlpack = np.from_dlpack(tensor)  # our DLPack capsule, consumed by numpy
    view = tensor.numpy()
    assert view.flags.writeable  # a render belongs to the caller
    assert np.shares_memory(via_dlpack, view)
    assert via_dlpack.ctypes.data == tensor.data_ptr
    np.testing.assert_array_equal(via_dlpack, atex.render(sample, camera, backend="cpu"))
    del tensor
    assert np.isfinite(via_dlpack).all()  # the capsule's owner keeps the image alive


def test_unconsumed_capsules_are_freed(sample):
    camera = atex.orbit_camera(sample, width=8, height=8)
    tensor = atex.render(sample, camera, backend="cpu", output="tensor")
    for _ in range(100):
        capsule = tensor.__dlpack__()
        assert type(capsule).__name__ == "PyCapsule"
        del capsule  # destructor path of a capsule nobody consumed


def test_deformed_gaussians_as_tensors(sample):
    g = sample.deform(0.25)
    tensors = g.tensors()
    assert set(tensors) == {"positions", "rotations", "log_scales", "opacity_logits", "sh"}
    positions = np.from_dlpack(tensors["positions"])
    assert positions.shape == (g.count, 3)
    assert np.shares_memory(positions, g.positions)
    assert not tensors["positions"].numpy().flags.writeable


def test_bad_arguments_raise(sample):
    camera = atex.orbit_camera(sample, width=8, height=8)
    with pytest.raises(atex.Error) as e:
        atex.render(sample, camera, backend="vulkan")
    assert e.value.name == "invalid-argument"
    with pytest.raises(atex.Error):
        atex.render(sample, camera, output="list")
    broken = atex.Camera(0, 0, 1, 1, 0, 0)
    with pytest.raises(atex.Error) as e:
        atex.render(sample, broken, backend="cpu")
    assert e.value.name == "invalid-argument"
    if not atex.HAVE_CUDA:
        with pytest.raises(atex.Error) as e:
            atex.render(sample, camera, backend="cuda")
        assert e.value.name == "no-device"


def test_dataset_views_and_images(lego):
    assert lego.kind == "dnerf-npz"
    assert len(lego.train_views) == 50 and len(lego.test_views) == 20
    view = lego.test_views[0]
    image = lego.image(view)
    assert image.shape == (view.camera.height, view.camera.width, 3)
    assert 0.0 <= image.min() and image.max() <= 1.0
    assert not image.flags.writeable  # shared with the dataset's image cache
    again = lego.image(view)
    assert np.shares_memory(image, again)  # the cached image, not a copy


def test_eval_matches_the_command_line(sample, lego):
    ours = atex.eval(sample, lego, backend="cpu")
    assert len(ours["views"]) == 20
    data = str(lego_path())
    out = subprocess.run([cli(), "eval", str(SAMPLE), "--data", data, "--backend", "cpu", "--json"],
                         capture_output=True, text=True, check=True).stdout
    theirs = json.loads(out)
    assert ours["mean"]["psnr"] == pytest.approx(theirs["mean"]["psnr"], abs=1e-9)
    assert ours["mean"]["ssim"] == pytest.approx(theirs["mean"]["ssim"], abs=1e-9)
    # A render of a test view is what eval compared.
    view = lego.test_views[3]
    image = np.clip(atex.render(sample, view.camera, backend="cpu"), 0, 1)
    target = lego.image(view)
    psnr = -10 * np.log10(np.mean((image.astype(np.float64) - target) ** 2))
    assert psnr == pytest.approx(ours["views"][3]["psnr"], abs=1e-3)


def lego_path():
    from conftest import require_data
    return require_data("dnerf_lego_tiny/tiny_dnerf_data.npz")


def test_eval_accepts_a_path(sample):
    result = atex.eval(sample, str(lego_path()), backend="cpu")
    assert result["mean"]["psnr"] > 15


def test_missing_dataset_raises(sample, tmp_path):
    with pytest.raises(atex.Error) as e:
        atex.eval(sample, str(tmp_path / "none"), backend="cpu")
    assert e.value.code in (atex.STATUS_CODES["not-found"], atex.STATUS_CODES["invalid-argument"])
