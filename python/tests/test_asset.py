"""atex.read / decode, the Asset's numpy views, write / to_bytes, deform, versions."""

import gc
import struct
import subprocess

import numpy as np
import pytest

import atex
from conftest import SAMPLE, SYNTHETIC_SAMPLE, SOURCE_DIR, require_data


def test_version_matches_the_version_file_and_the_command():
    version = (SOURCE_DIR / "VERSION").read_text().strip()
    assert atex.__version__ == version
    import os
    binary = os.path.join(os.environ.get("ATEX_BINARY_DIR", str(SOURCE_DIR / "build")), "bin", "atex")
    if os.path.exists(binary):
        out = subprocess.run([binary, "--version"], capture_output=True, text=True, check=True).stdout
        assert out.split()[1] == version
        assert f"format {atex.FORMAT_VERSION[0]}.{atex.FORMAT_VERSION[1]}" in out


def test_written_header_carries_the_format_version(sample):
    # The writer puts the lowest version whose chunks the file uses: 1.0 without time windows
    # (GTWN, new in 1.1); this build reads up to atex.FORMAT_VERSION.
    data = sample.to_bytes()
    major, minor = struct.unpack_from("<HH", data, 8)
    assert major == atex.FORMAT_VERSION[0]
    assert sample.gaussians.time_windows is None
    assert minor == 0 <= atex.FORMAT_VERSION[1]


def test_another_major_version_is_refused(sample):
    data = bytearray(sample.to_bytes())
    struct.pack_into("<H", data, 8, atex.FORMAT_VERSION[0] + 1)
    with pytest.raises(atex.Error) as e:
        atex.decode(bytes(data))
    assert e.value.name == "unsupported-version"
    assert e.value.code == atex.STATUS_CODES["unsupported-version"] == 5


def test_read_gives_shapes_of_the_model(sample):
    n = sample.gaussian_count
    assert n > 0 and len(sample) == n
    g = sample.gaussians
    assert g.positions.shape == (n, 3) and g.positions.dtype == np.float32
    assert g.rotations.shape == (n, 4)
    assert g.log_scales.shape == (n, 3)
    assert g.opacity_logits.shape == (n,)
    k = (sample.sh_degree + 1) ** 2
    assert g.sh.shape == (n, k, 3)
    assert np.isfinite(g.positions).all()
    lo, hi = sample.metadata["bounds_min"], sample.metadata["bounds_max"]
    assert (g.positions.min(axis=0) >= np.array(lo) - 1e-4).all()
    assert (g.positions.max(axis=0) <= np.array(hi) + 1e-4).all()


def test_views_share_memory_and_keep_the_asset_alive():
    asset = atex.read(str(SAMPLE))
    a = asset.gaussians.positions
    b = asset.gaussians.positions
    assert np.shares_memory(a, b)  # both views of the one C++ array: no copy
    assert not a.flags.writeable
    with pytest.raises(ValueError):
        a[0, 0] = 1.0
    expected = a.copy()
    del asset, b
    gc.collect()
    np.testing.assert_array_equal(a, expected)  # the view kept the asset alive


def test_textures_pool_and_layout(sample):
    pool = sample.textures
    assert pool is not None
    n = sample.gaussian_count
    h, w = pool.heights.astype(np.int64), pool.widths.astype(np.int64)
    assert set(np.unique(h)) <= {1, 2, 4} and set(np.unique(w)) <= {1, 2, 4}
    assert (pool.axis_u != pool.axis_v).all()
    assert pool.offsets.shape == (n + 1,)
    np.testing.assert_array_equal(np.diff(pool.offsets.astype(np.int64)), h * w)
    assert pool.texels.shape == (pool.texel_count, 4)
    assert sum(pool.histogram().values()) == n


def test_deformation_grids_and_weights(sample):
    field = sample.deformation
    assert field is not None
    cfg = field.config
    planes = field.planes
    assert len(planes) == len(cfg["multires"]) and all(len(p) == 6 for p in planes)
    c = cfg["channels"]
    res = cfg["base_resolution"]
    # plane xy of scale 0 is [C][res_y][res_x]; plane xt is [C][res_t][res_x]
    assert planes[0][0].shape == (c, res[1] * cfg["multires"][0], res[0] * cfg["multires"][0])
    assert planes[0][2].shape == (c, res[3], res[0] * cfg["multires"][0])
    weight, bias = field.trunk[0]
    assert weight.shape == (cfg["mlp_width"], c * len(cfg["multires"])) and bias.shape == (cfg["mlp_width"],)
    for on, head in zip(cfg["heads"], field.heads):
        assert (head is not None) == on
    total = sum(p.size for s in planes for p in s) + sum(w.size + b.size for w, b in field.trunk)
    total += sum(w.size + b.size for head in field.heads if head for w, b in head)
    assert total == field.parameter_count


def test_write_then_read_round_trips(sample, tmp_path):
    path = tmp_path / "copy.atex"
    sample.write(str(path))
    back = atex.read(str(path))
    np.testing.assert_array_equal(back.gaussians.positions, sample.gaussians.positions)
    np.testing.assert_array_equal(back.textures.texels, sample.textures.texels)
    np.testing.assert_array_equal(back.deformation.planes[0][0], sample.deformation.planes[0][0])
    assert back.file_encodings == sample.file_encodings
    assert path.read_bytes() == sample.to_bytes()  # deterministic writer


def test_write_codecs_and_encodings(sample, tmp_path):
    raw = sample.to_bytes(codec="raw", encodings={"positions": "f32"})
    small = sample.to_bytes(codec="shuffle-zstd", encodings={"texels": "q8", "positions": "f16"})
    assert len(small) < len(raw)
    back = atex.decode(small)
    assert back.file_encodings["texels"] == "q8" and back.file_encodings["positions"] == "f16"
    np.testing.assert_allclose(back.gaussians.positions, sample.gaussians.positions, atol=1e-2, rtol=1e-2)
    with pytest.raises(atex.Error) as e:
        sample.to_bytes(codec="lzma")
    assert e.value.name == "invalid-argument"
    with pytest.raises(atex.Error):
        sample.to_bytes(encodings={"nonsense": "f16"})


def test_deform_moves_gaussians_over_time(sample):
    t0, t1 = sample.time_range
    a = sample.deform(t0)
    b = sample.deform(t1)
    assert a.positions.shape == sample.gaussians.positions.shape
    assert not np.array_equal(a.positions, b.positions)  # the field moves them
    again = sample.deform(t0)
    np.testing.assert_array_equal(a.positions, again.positions)  # deterministic
    assert not np.shares_memory(a.positions, sample.gaussians.positions)


def test_static_asset_deforms_to_itself():
    asset = atex.read(str(SYNTHETIC_SAMPLE))
    if asset.deformation is None:
        g = asset.deform(0.3)
        np.testing.assert_array_equal(g.positions, asset.gaussians.positions)


def test_read_other_formats_through_the_converters():
    ply = require_data("splats/kacytran1122_try_iter7000_point_cloud.ply")
    asset = atex.read(str(ply))
    assert asset.gaussian_count == 9080 and asset.sh_degree == 3
    assert asset.file_encodings is None


def test_missing_file_raises_not_found(tmp_path):
    with pytest.raises(atex.Error) as e:
        atex.read(str(tmp_path / "nothing.atex"))
    assert e.value.name == "not-found" and e.value.code == 12
    assert "nothing.atex" in e.value.message
    assert str(e.value).startswith("E12 not-found")
