"""Hostile files raise atex.Error and never crash the interpreter. Labelled `hostile` in ctest,
so tests/sanitize.sh runs this file again with the module built under ASan + UBSan."""

import random

import pytest

import atex
from conftest import SAMPLE, SYNTHETIC_SAMPLE


@pytest.fixture(scope="module")
def good_bytes():
    return SYNTHETIC_SAMPLE.read_bytes()


def expect_error(data, **kwargs):
    with pytest.raises(atex.Error) as e:
        atex.decode(bytes(data), **kwargs)
    assert e.value.code > 0 and e.value.message
    return e.value


def test_empty_and_garbage():
    assert expect_error(b"").name in ("truncated", "bad-magic")
    assert expect_error(b"\x00" * 64).name == "bad-magic"
    assert expect_error(b"PK\x03\x04" + b"\x00" * 100).name == "bad-magic"


def test_truncations_are_refused(good_bytes):
    step = max(1, len(good_bytes) // 300)
    for end in list(range(0, len(good_bytes), step)) + [len(good_bytes) - 1]:
        err = expect_error(good_bytes[:end])
        assert err.name in ("truncated", "bad-magic", "corrupt"), (end, str(err))


def test_corrupted_bytes_are_refused_or_decoded_validly(good_bytes):
    rng = random.Random(22)
    for trial in range(300):
        data = bytearray(good_bytes)
        for _ in range(rng.randint(1, 8)):
            data[rng.randrange(len(data))] = rng.randrange(256)
        if data == bytearray(good_bytes):
            continue
        # With checksums every change is caught; without them the structural checks must hold.
        expect_error(data)
        try:
            asset = atex.decode(bytes(data), verify_checksums=False)
        except atex.Error as e:
            assert e.code > 0
        else:
            assert asset.gaussian_count >= 0
            asset.gaussians.positions.tobytes()  # the arrays it returns are real memory


def test_corrupted_real_asset_without_checksums():
    good = SAMPLE.read_bytes()
    rng = random.Random(7)
    for trial in range(40):
        data = bytearray(good)
        for _ in range(rng.randint(1, 4)):
            data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
        try:
            asset = atex.decode(bytes(data), verify_checksums=False)
        except atex.Error as e:
            assert e.code > 0
        else:
            if asset.deformation is not None:
                asset.deform(0.5)


def test_header_fields_out_of_range(good_bytes):
    data = bytearray(good_bytes)
    data[16:24] = (1 << 62).to_bytes(8, "little")  # file_size far beyond the real size
    expect_error(data)
    data = bytearray(good_bytes)
    data[24:28] = (0xFFFFFFFF).to_bytes(4, "little")  # chunk count
    expect_error(data, verify_checksums=False)


def test_hostile_files_on_disk(tmp_path):
    path = tmp_path / "bad.atex"
    path.write_bytes(SAMPLE.read_bytes()[:1000])
    with pytest.raises(atex.Error) as e:
        atex.read(str(path))
    assert str(path) in e.value.message
    ply = tmp_path / "bad.ply"
    ply.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 1000000\nproperty float x\nend_header\n\x00\x00")
    with pytest.raises(atex.Error):
        atex.read(str(ply))
    with pytest.raises(atex.Error):
        atex.read(str(tmp_path))  # a folder read as 4DGaussians output: nothing there
