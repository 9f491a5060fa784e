"""Shared fixtures: where the repository's samples and the real test data are."""

import os
import pathlib

import pytest

SOURCE_DIR = pathlib.Path(os.environ.get("ATEX_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
SAMPLE = SOURCE_DIR / "samples" / "lego_adaptive_2MiB.atex"
SYNTHETIC_SAMPLE = SOURCE_DIR / "samples" / "sample.atex"


def data_dir():
    for var in ("ATEX_DATA_DIR", "ATEX_DATA_DIR_DEFAULT"):
        if os.environ.get(var):
            return pathlib.Path(os.environ[var])
    return SOURCE_DIR.parent / "shared" / "data"


def require_data(relative):
    """The path of a real-data file; skips (or fails under ATEX_REQUIRE_DATA=1) when it is missing."""
    path = data_dir() / relative
    if not path.exists():
        if os.environ.get("ATEX_REQUIRE_DATA") == "1":
            pytest.fail(f"missing test data {path} (ATEX_REQUIRE_DATA=1)")
        pytest.skip(f"missing test data {path}")
    return path


@pytest.fixture(scope="session")
def sample():
    import atex
    return atex.read(str(SAMPLE))


@pytest.fixture(scope="session")
def lego():
    import atex
    return atex.Dataset(str(require_data("dnerf_lego_tiny/tiny_dnerf_data.npz")))
