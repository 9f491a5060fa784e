"""The module on a GPU machine with PyTorch (bench/device/python_gpu.sh runs it there): CUDA renders,
and torch.from_dlpack taking atex tensors without a copy. Skips without torch, a CUDA build or a
device, unless ATEX_REQUIRE_GPU=1, which makes those a failure."""

import os

import numpy as np
import pytest

import atex


def need(condition, why):
    if not condition:
        if os.environ.get("ATEX_REQUIRE_GPU") == "1":
            pytest.fail(f"{why} (ATEX_REQUIRE_GPU=1)")
        pytest.skip(why)


@pytest.fixture(scope="module")
def torch():
    try:
        import torch as module
    except ImportError:
        module = None
    need(module is not None, "PyTorch is not installed")
    return module


def test_from_dlpack_shares_the_render(torch, sample):
    camera = atex.orbit_camera(sample, width=64, height=48)
    tensor = atex.render(sample, camera, backend="cpu", output="tensor")
    t = torch.from_dlpack(tensor)
    assert t.data_ptr() == tensor.data_ptr  # the same memory: no copy
    assert tuple(t.shape) == (48, 64, 3) and t.dtype == torch.float32
    np.testing.assert_array_equal(t.numpy(), tensor.numpy())
    del tensor
    assert torch.isfinite(t).all()  # the consumer keeps the image alive


def test_from_dlpack_shares_deformed_gaussians(torch, sample):
    g = sample.deform(0.5)
    tensors = g.tensors()
    positions = torch.from_dlpack(tensors["positions"])
    assert positions.data_ptr() == tensors["positions"].data_ptr
    assert positions.data_ptr() == g.positions.ctypes.data
    assert tuple(positions.shape) == (g.count, 3)


def test_cuda_render_stays_on_the_device_and_matches_the_cpu_reference(torch, sample):
    need(atex.HAVE_CUDA, "this build of the module has no CUDA backend")
    need(torch.cuda.is_available(), "no CUDA device")
    camera = atex.orbit_camera(sample, width=160, height=120, t=0.3)
    cuda = atex.render(sample, camera, backend="cuda", output="tensor")
    cpu = atex.render(sample, camera, backend="cpu")
    assert cuda.__dlpack_device__() == (2, 0)  # kDLCUDA: the render never came to the host
    assert cuda.device == "cuda"
    t = torch.from_dlpack(cuda)
    assert t.is_cuda and t.data_ptr() == cuda.data_ptr  # the same device memory: no copy
    assert tuple(t.shape) == (120, 160, 3) and t.dtype == torch.float32
    with pytest.raises(Exception):
        cuda.numpy()  # device memory has no numpy view
    mse = float(np.mean((np.clip(t.cpu().numpy(), 0, 1) - np.clip(cpu, 0, 1)) ** 2))
    assert mse == 0 or -10 * np.log10(mse) > 35  # TF32 MLP on the GPU: close, not bit-equal


def test_a_held_device_render_is_not_overwritten_by_the_next(torch, sample):
    need(atex.HAVE_CUDA and torch.cuda.is_available(), "no CUDA build or device")
    camera = atex.orbit_camera(sample, width=64, height=48, t=0.1)
    first = torch.from_dlpack(atex.render(sample, camera, backend="cuda", output="tensor"))
    kept = first.clone()
    later = atex.orbit_camera(sample, azimuth_deg=80.0, width=64, height=48, t=0.9)
    second = torch.from_dlpack(atex.render(sample, later, backend="cuda", output="tensor"))
    assert second.data_ptr() != first.data_ptr()  # the backend took a new buffer: `first` is held
    assert torch.equal(first, kept)
    del first, kept
    torch.cuda.synchronize()
    assert torch.isfinite(second).all()


def test_cuda_backend_is_chosen_by_auto(torch, sample):
    need(atex.HAVE_CUDA and torch.cuda.is_available(), "no CUDA build or device")
    camera = atex.orbit_camera(sample, width=32, height=24)
    a = atex.render(sample, camera, backend="auto")
    b = atex.render(sample, camera, backend="cuda")
    np.testing.assert_allclose(a, b, atol=1e-5)
