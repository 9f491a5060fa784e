"""An in-tree PEP 517 build backend for the `atex` Python package (docs/python.md says why).

pip builds the package with nothing downloaded: pyproject.toml names this file
(`requires = []`, `backend-path = ["python/build_backend"]`), and this backend runs the
project's own CMake build (Debian's cmake, pybind11-dev and python3-dev) for the interpreter
that runs pip, then packs python/atex and the extension into a wheel (the binary distribution
format: a zip with <name>.dist-info/{METADATA, WHEEL, RECORD}).

Hooks: build_wheel, build_editable (PEP 660: a .pth file pointing at the CMake build's
python/ folder, so a rebuild of the atex_python target is picked up), build_sdist (the
files of the source tree that the build needs), and the get_requires_* hooks (nothing).

Settings (pip --config-settings KEY=VALUE, or the environment):
  build-dir / ATEX_PIP_BUILD_DIR   the CMake build folder (default: build-python in the source)
  cmake-args / CMAKE_ARGS          extra CMake arguments, e.g. "-DATEX_CUDA=OFF"
  jobs / ATEX_JOBS                 parallel build jobs (default: the CPU count)
"""

import base64
import hashlib
import io
import os
import pathlib
import shlex
import subprocess
import sys
import sysconfig
import tarfile
import zipfile

SOURCE = pathlib.Path(__file__).resolve().parents[2]
NAME = "atex"
# What an sdist carries: everything the CMake build of the module needs.
SDIST_PATHS = ["VERSION", "CMakeLists.txt", "pyproject.toml", "README.md", "cmake", "libatex", "converters",
               "kernels", "tools", "python", "format_spec", "samples/lego_adaptive_2MiB.atex"]


def _version():
    return (SOURCE / "VERSION").read_text().strip()


def _project():
    """The [project] table of pyproject.toml (summary, Python requirement, dependencies)."""
    try:
        import tomllib
    except ImportError:  # Python < 3.11: the fields this backend needs, as pyproject.toml has them
        return {"description": "libatex bindings", "requires-python": ">=3.8", "dependencies": ["numpy>=1.22"]}
    with open(SOURCE / "pyproject.toml", "rb") as f:
        return tomllib.load(f).get("project", {})


def _metadata():
    p = _project()
    lines = ["Metadata-Version: 2.1", f"Name: {NAME}", f"Version: {_version()}",
             f"Summary: {p.get('description', '')}"]
    if "requires-python" in p:
        lines.append(f"Requires-Python: {p['requires-python']}")
    lines += [f"Requires-Dist: {d}" for d in p.get("dependencies", [])]
    lic = p.get("license", {})
    if isinstance(lic, dict) and "text" in lic:
        lines.append(f"License: {lic['text']}")
    return "\n".join(lines) + "\n"


def _tag():
    """The wheel tag of the running interpreter: cp311-cp311-linux_x86_64."""
    impl = f"cp{sys.version_info.major}{sys.version_info.minor}"
    abi = impl + getattr(sys, "abiflags", "")
    platform = sysconfig.get_platform().replace("-", "_").replace(".", "_")
    return f"{impl}-{abi}-{platform}"


def _setting(config_settings, key, env, default):
    if config_settings and key in config_settings:
        return config_settings[key]
    return os.environ.get(env, default)


def _build(config_settings):
    """Configures and builds the extension; returns the folder holding the assembled package."""
    build_dir = pathlib.Path(_setting(config_settings, "build-dir", "ATEX_PIP_BUILD_DIR", SOURCE / "build-python"))
    extra = shlex.split(_setting(config_settings, "cmake-args", "CMAKE_ARGS", ""))
    jobs = str(_setting(config_settings, "jobs", "ATEX_JOBS", os.cpu_count() or 1))
    configure = ["cmake", "-S", str(SOURCE), "-B", str(build_dir), "-DATEX_PYTHON=ON",
                 f"-DPython3_EXECUTABLE={sys.executable}", *extra]
    if not (build_dir / "CMakeCache.txt").exists():
        # A fresh build folder: only what the module needs. An existing one (e.g. build-dir=build)
        # keeps its own settings, so its tests and benchmarks stay configured.
        configure += ["-DCMAKE_BUILD_TYPE=Release", "-DATEX_TESTS=OFF", "-DATEX_BENCHMARKS=OFF"]
    for command in (configure, ["cmake", "--build", str(build_dir), "--target", "atex_python", "-j", jobs]):
        print("atex build backend:", " ".join(command), file=sys.stderr, flush=True)
        subprocess.run(command, check=True, stdout=sys.stderr)  # pip shows stderr with -v
    package = build_dir / "python" / NAME
    if not any(package.glob("_atex*.so")):
        raise RuntimeError(f"the build produced no extension in {package}")
    return build_dir / "python"


def _record_line(name, data):
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return f"{name},sha256={digest},{len(data)}"


def _write_wheel(wheel_directory, files):
    """files: [(name inside the wheel, bytes)]. Adds the .dist-info and returns the wheel's name."""
    dist_info = f"{NAME}-{_version()}.dist-info"
    tag = _tag()
    files = list(files) + [
        (f"{dist_info}/METADATA", _metadata().encode()),
        (f"{dist_info}/WHEEL", (f"Wheel-Version: 1.0\nGenerator: atex_build_backend {_version()}\n"
                                f"Root-Is-Purelib: false\nTag: {tag}\n").encode()),
    ]
    record = [_record_line(name, data) for name, data in files] + [f"{dist_info}/RECORD,,"]
    files.append((f"{dist_info}/RECORD", ("\n".join(record) + "\n").encode()))
    wheel_name = f"{NAME}-{_version()}-{tag}.whl"
    with zipfile.ZipFile(pathlib.Path(wheel_directory) / wheel_name, "w", zipfile.ZIP_DEFLATED) as wheel:
        for name, data in files:
            info = zipfile.ZipInfo(name, date_time=(2026, 1, 1, 0, 0, 0))
            info.external_attr = (0o755 if name.endswith(".so") else 0o644) << 16
            info.compress_type = zipfile.ZIP_DEFLATED
            wheel.writestr(info, data)
    return wheel_name


def get_requires_for_build_wheel(config_settings=None):
    return []


def get_requires_for_build_editable(config_settings=None):
    return []


def get_requires_for_build_sdist(config_settings=None):
    return []


def build_wheel(wheel_directory, config_settings=None, metadata_directory=None):
    root = _build(config_settings)
    files = []
    for path in sorted((root / NAME).iterdir()):
        if path.is_file() and (path.suffix in (".py", ".pyi", ".so") or path.name == "py.typed"):
            files.append((f"{NAME}/{path.name}", path.read_bytes()))
    return _write_wheel(wheel_directory, files)


def build_editable(wheel_directory, config_settings=None, metadata_directory=None):
    root = _build(config_settings)
    # A .pth line is added to sys.path at start-up: the package is imported from the build tree.
    return _write_wheel(wheel_directory, [(f"_{NAME}_editable.pth", (str(root.resolve()) + "\n").encode())])


def build_sdist(sdist_directory, config_settings=None):
    base = f"{NAME}-{_version()}"
    name = f"{base}.tar.gz"
    skip = {"__pycache__", ".pytest_cache"}
    with tarfile.open(pathlib.Path(sdist_directory) / name, "w:gz", format=tarfile.PAX_FORMAT) as tar:
        for entry in SDIST_PATHS:
            path = SOURCE / entry
            if path.exists():
                tar.add(path, arcname=f"{base}/{entry}", filter=lambda t: None if set(t.name.split("/")) & skip else t)
        pkg_info = _metadata().encode()
        info = tarfile.TarInfo(f"{base}/PKG-INFO")
        info.size = len(pkg_info)
        tar.addfile(info, io.BytesIO(pkg_info))
    return name
