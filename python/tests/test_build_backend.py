"""The in-tree PEP 517 backend (python/build_backend): the wheel it writes follows the wheel format
(RECORD digests, WHEEL tag of this interpreter, METADATA version from VERSION) and pip installs it;
editable and sdist builds. The CMake step is replaced by a prepared folder here (ctest builds the
module itself); `pip install .` end to end is in docs/python.md."""

import base64
import hashlib
import importlib.util
import subprocess
import sys
import sysconfig
import tarfile
import zipfile

import pytest

from conftest import SOURCE_DIR


@pytest.fixture()
def backend(tmp_path, monkeypatch):
    spec = importlib.util.spec_from_file_location(
        "atex_build_backend", SOURCE_DIR / "python" / "build_backend" / "atex_build_backend.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    root = tmp_path / "built"
    (root / "atex").mkdir(parents=True)
    (root / "atex" / "__init__.py").write_text("VALUE = 22\n")
    (root / "atex" / "_atex.cpython-311-x86_64-linux-gnu.so").write_bytes(b"\x7fELF not really")
    (root / "atex" / "ignored.txt").write_text("not packaged")
    monkeypatch.setattr(module, "_build", lambda config_settings: root)
    return module


def test_wheel_layout_record_and_tag(backend, tmp_path):
    assert backend.get_requires_for_build_wheel() == []
    name = backend.build_wheel(str(tmp_path))
    version = (SOURCE_DIR / "VERSION").read_text().strip()
    impl = f"cp{sys.version_info.major}{sys.version_info.minor}"
    platform = sysconfig.get_platform().replace("-", "_").replace(".", "_")
    assert name == f"atex-{version}-{impl}-{impl}{sys.abiflags}-{platform}.whl"
    with zipfile.ZipFile(tmp_path / name) as wheel:
        names = set(wheel.namelist())
        dist = f"atex-{version}.dist-info"
        assert {"atex/__init__.py", "atex/_atex.cpython-311-x86_64-linux-gnu.so", f"{dist}/METADATA",
                f"{dist}/WHEEL", f"{dist}/RECORD"} == names
        metadata = wheel.read(f"{dist}/METADATA").decode()
        assert f"Version: {version}" in metadata and "Name: atex" in metadata
        assert "Requires-Dist: numpy" in metadata
        assert "Root-Is-Purelib: false" in wheel.read(f"{dist}/WHEEL").decode()
        rows = [line.split(",") for line in wheel.read(f"{dist}/RECORD").decode().splitlines()]
        assert {r[0] for r in rows} == names
        for path, digest, size in rows:
            if path.endswith("RECORD"):
                assert digest == size == ""
                continue
            data = wheel.read(path)
            expected = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
            assert digest == f"sha256={expected}" and int(size) == len(data)


def test_pip_installs_the_wheel(backend, tmp_path):
    if subprocess.run([sys.executable, "-m", "pip", "--version"], capture_output=True).returncode != 0:
        pytest.skip("pip is not available for this interpreter")
    name = backend.build_wheel(str(tmp_path))
    target = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--no-index", "--no-deps", "--no-compile", "--target",
                    str(target), str(tmp_path / name)], check=True, capture_output=True)
    assert (target / "atex" / "__init__.py").read_text() == "VALUE = 22\n"
    assert (target / "atex" / "_atex.cpython-311-x86_64-linux-gnu.so").exists()


def test_editable_and_sdist(backend, tmp_path):
    name = backend.build_editable(str(tmp_path))
    with zipfile.ZipFile(tmp_path / name) as wheel:
        pth = [n for n in wheel.namelist() if n.endswith(".pth")]
        assert pth and wheel.read(pth[0]).decode().strip() == str(tmp_path / "built")
    sdist = backend.build_sdist(str(tmp_path))
    with tarfile.open(tmp_path / sdist) as tar:
        names = tar.getnames()
    base = sdist[:-len(".tar.gz")]
    for required in ("VERSION", "CMakeLists.txt", "pyproject.toml", "PKG-INFO", "python/atex/__init__.py",
                     "libatex/include/atex/container.h"):
        assert f"{base}/{required}" in names
    assert not any("__pycache__" in n for n in names)
