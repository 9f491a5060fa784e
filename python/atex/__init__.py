"""libatex from Python: read, write, deform, render, evaluate, fit and train AdaTex4D assets.

The API follows the C++ library (libatex/include/atex/*.h), not the command line:

    import atex
    asset = atex.read("samples/lego_adaptive_2MiB.atex")
    asset.gaussians.positions          # [N, 3] float32 numpy view of the C++ array (no copy)
    g = asset.deform(0.5)              # the Gaussians at scene time 0.5
    image = atex.render(asset, camera, t=0.5)          # [H, W, 3] float32
    fitted, report = atex.fit(asset, budget="1MiB")
    fitted.write("lego_1MiB.atex")

Errors raise atex.Error, carrying the libatex status code (.code, .name) and message.
Renders and deformed Gaussians are also available as atex.Tensor (DLPack), which
torch.from_dlpack takes without a copy. docs/python.md has the whole story.
"""

from ._atex import (  # noqa: F401  (re-exported API)
    FORMAT_VERSION,
    HAVE_CUDA,
    HAVE_DRACO,
    STATUS_CODES,
    Asset,
    Camera,
    Dataset,
    DeformationField,
    Error,
    Gaussians,
    Tensor,
    TexturePool,
    View,
    __version__,
    convert,
    decode,
    eval,  # noqa: A001  (atex.eval mirrors `atex eval`; the builtin is untouched outside this module)
    export_gltf,
    fit,
    read,
    render,
    train,
)
from ._cameras import orbit_camera  # noqa: F401

__all__ = [
    "FORMAT_VERSION", "HAVE_CUDA", "HAVE_DRACO", "STATUS_CODES", "Asset", "Camera", "Dataset",
    "DeformationField", "Error", "Gaussians", "Tensor", "TexturePool", "View", "__version__",
    "convert", "decode", "eval", "export_gltf", "fit", "orbit_camera", "read", "render", "train",
]
