# Type stubs of the atex package (the extension atex._atex and atex._cameras). Docstrings are
# in the extension itself (help(atex.fit)); docs/python.md describes the API.
from os import PathLike
from typing import Any, Callable, Dict, List, Literal, Optional, Sequence, Tuple, Union, overload

import numpy as np
import numpy.typing as npt

__version__: str
FORMAT_VERSION: Tuple[int, int]
HAVE_CUDA: bool
HAVE_DRACO: bool
STATUS_CODES: Dict[str, int]

Float32Array = npt.NDArray[np.float32]
Backend = Literal["auto", "cuda", "cpu"]
Budget = Union[int, str]

class Error(Exception):
    """An error reported by libatex: code (status number), name ('checksum-mismatch'), message."""
    code: int
    name: str
    message: str

class Tensor:
    """C++-owned memory exchanged through DLPack (torch.from_dlpack, numpy.from_dlpack) without a copy."""
    @property
    def shape(self) -> Tuple[int, ...]: ...
    @property
    def dtype(self) -> np.dtype: ...
    @property
    def device(self) -> str: ...
    @property
    def data_ptr(self) -> int: ...
    def __dlpack__(self, *, stream: Any = None, max_version: Optional[Tuple[int, int]] = None,
                   dl_device: Optional[Tuple[int, int]] = None, copy: Optional[bool] = None) -> Any: ...
    def __dlpack_device__(self) -> Tuple[int, int]: ...
    def numpy(self) -> np.ndarray: ...
    def __array__(self, dtype: Any = None) -> np.ndarray: ...

class Gaussians:
    """Gaussian parameters as read-only numpy views (atex/model.h, BasicGaussians)."""
    @property
    def count(self) -> int: ...
    def __len__(self) -> int: ...
    @property
    def sh_degree(self) -> int: ...
    @property
    def positions(self) -> Float32Array: ...       # [N, 3]
    @property
    def rotations(self) -> Float32Array: ...       # [N, 4] (w, x, y, z)
    @property
    def log_scales(self) -> Float32Array: ...      # [N, 3]
    @property
    def opacity_logits(self) -> Float32Array: ...  # [N]
    @property
    def sh(self) -> Float32Array: ...              # [N, K, 3]
    @property
    def time_windows(self) -> Optional[Float32Array]: ...  # [N, 2] (centre, inverse width), or None
    def tensors(self) -> Dict[str, Tensor]: ...

class TexturePool:
    """The packed texture pool (atex/model.h, BasicTexturePool) as read-only numpy views."""
    @property
    def heights(self) -> npt.NDArray[np.uint8]: ...
    @property
    def widths(self) -> npt.NDArray[np.uint8]: ...
    @property
    def axis_u(self) -> npt.NDArray[np.uint8]: ...
    @property
    def axis_v(self) -> npt.NDArray[np.uint8]: ...
    @property
    def offsets(self) -> npt.NDArray[np.uint64]: ...
    @property
    def texels(self) -> Float32Array: ...          # [texel_count, 4]
    @property
    def texel_count(self) -> int: ...
    def histogram(self) -> Dict[str, int]: ...

LinearLayer = Tuple[Float32Array, Float32Array]  # (weight [out, in], bias [out])

class DeformationField:
    """HexPlane grids + MLP (atex/model.h, docs/conventions.md §3) as read-only numpy views."""
    @property
    def config(self) -> Dict[str, Any]: ...
    @property
    def planes(self) -> List[List[Float32Array]]: ...  # [scale][plane] -> [C, res_b, res_a]
    @property
    def trunk(self) -> List[LinearLayer]: ...
    @property
    def heads(self) -> List[Optional[Tuple[LinearLayer, LinearLayer]]]: ...
    @property
    def parameter_count(self) -> int: ...

Encoding = Literal["f32", "f16", "q16", "q8"]
Codec = Literal["raw", "zstd", "shuffle-zstd", "delta-shuffle-zstd", "draco"]

class Asset:
    """An immutable AdaTex4D asset; its arrays are read-only numpy views of the C++ memory."""
    @property
    def gaussian_count(self) -> int: ...
    def __len__(self) -> int: ...
    @property
    def sh_degree(self) -> int: ...
    @property
    def gaussians(self) -> Gaussians: ...
    @property
    def textures(self) -> Optional[TexturePool]: ...
    @property
    def deformation(self) -> Optional[DeformationField]: ...
    @property
    def stats(self) -> Optional[Dict[str, Float32Array]]: ...
    @property
    def metadata(self) -> Dict[str, Any]: ...
    @property
    def time_range(self) -> Tuple[float, float]: ...
    @property
    def file_encodings(self) -> Optional[Dict[str, Encoding]]: ...
    def deform(self, t: float) -> Gaussians: ...
    def to_bytes(self, codec: Codec = "shuffle-zstd", zstd_level: int = 3,
                 encodings: Optional[Dict[str, Encoding]] = None, keep_stats: bool = True) -> bytes: ...
    def write(self, path: str, codec: Codec = "shuffle-zstd", zstd_level: int = 3,
              encodings: Optional[Dict[str, Encoding]] = None, keep_stats: bool = True) -> None: ...

class Camera:
    """Pinhole camera, OpenCV convention (atex/camera.h)."""
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    world_to_camera: List[float]  # 16 numbers, row-major 4x4
    time: float
    name: str
    def __init__(self, width: int, height: int, fx: float, fy: float, cx: float, cy: float,
                 world_to_camera: Sequence[float] = ..., time: float = 0.0, name: str = "") -> None: ...
    @property
    def center(self) -> List[float]: ...

class View:
    @property
    def camera(self) -> Camera: ...
    @property
    def camera_id(self) -> int: ...
    @property
    def timestep(self) -> int: ...
    @property
    def image_path(self) -> str: ...

class Dataset:
    """A multi-view video dataset (atex/dataset.h)."""
    def __init__(self, path: str, kind: str = "auto", timesteps: int = 0, downscale: int = 1,
                 test_cameras: Sequence[int] = ...) -> None: ...
    @property
    def name(self) -> str: ...
    @property
    def kind(self) -> str: ...
    @property
    def train_views(self) -> List[View]: ...
    @property
    def test_views(self) -> List[View]: ...
    @property
    def timestep_count(self) -> int: ...
    @property
    def time_range(self) -> Tuple[float, float]: ...
    @property
    def background(self) -> List[float]: ...
    @property
    def warnings(self) -> List[str]: ...
    def image(self, view: View) -> Float32Array: ...

DatasetArg = Union[Dataset, str, "PathLike[str]"]

def read(path: str, format: str = "", verify_checksums: bool = True) -> Asset: ...
def decode(data: bytes, verify_checksums: bool = True) -> Asset: ...

@overload
def render(asset: Asset, camera: Camera, t: Optional[float] = None, backend: Backend = "auto",
           background: Optional[Sequence[float]] = None, near_plane: Optional[float] = None,
           output: Literal["numpy"] = "numpy") -> Float32Array: ...
@overload
def render(asset: Asset, camera: Camera, t: Optional[float] = None, backend: Backend = "auto",
           background: Optional[Sequence[float]] = None, near_plane: Optional[float] = None,
           output: Literal["tensor"] = ...) -> Tensor: ...

def eval(asset: Asset, dataset: DatasetArg, split: Literal["test", "train"] = "test", backend: Backend = "auto",
         near_plane: Optional[float] = None) -> Dict[str, Any]: ...

@overload
def fit(asset: Asset, budget: Optional[Budget] = None, *, dataset: Optional[DatasetArg] = None,
        levers: str = "default", probes: int = 8, probe_size: int = 256, backend: Backend = "auto",
        seed: int = 6666, keep_stats: bool = False,
        progress: Optional[Callable[[Dict[str, Any]], Optional[bool]]] = None, quality: float = 0.0,
        keep_count: float = 0.0, eval_views: int = 0, step_growth: float = 2.0,
        min_texture_step: float = 0.00390625, parallel_candidates: int = 0) -> Tuple[Asset, Dict[str, Any]]: ...
@overload
def fit(asset: Asset, budget: Sequence[Budget], *, dataset: Optional[DatasetArg] = None, levers: str = "default",
        probes: int = 8, probe_size: int = 256, backend: Backend = "auto", seed: int = 6666,
        keep_stats: bool = False,
        progress: Optional[Callable[[Dict[str, Any]], Optional[bool]]] = None, quality: float = 0.0,
        keep_count: float = 0.0, eval_views: int = 0, step_growth: float = 2.0,
        min_texture_step: float = 0.00390625,
        parallel_candidates: int = 0) -> List[Tuple[Asset, Dict[str, Any]]]: ...

def train(dataset: DatasetArg, config: Optional[Dict[str, Any]] = None, *,
          progress: Optional[Callable[[Dict[str, Any]], Optional[bool]]] = None, backend: Backend = "auto",
          stages: Literal["1", "2", "all"] = "all", init: Optional[Asset] = None, time_limit: float = 0.0,
          checkpoint_dir: str = "") -> Tuple[Asset, Dict[str, Any]]: ...

def convert(input: str, output: str, *, from_format: str = "", to_format: str = "", time: Optional[float] = None,
            frames: Optional[str] = None, spz_version: int = 4,
            progress: Optional[Callable[[str, float], Optional[bool]]] = None) -> Dict[str, Any]: ...

def export_gltf(asset: Asset, path: str, *, spz: bool = False, meshopt: bool = False, meshopt_bits: int = 0,
                quantize: bool = False, bake_textures: bool = False, time: Optional[float] = None,
                textures: bool = True, deformation: bool = True, raw: bool = True,
                up: Optional[str] = None) -> Dict[str, Any]: ...

def orbit_camera(asset: Asset, azimuth_deg: float = 30.0, elevation_deg: float = 20.0, width: int = 256,
                 height: int = 192, fov_y_deg: float = 50.0, distance_scale: float = 2.5, t: float = 0.0) -> Camera: ...
