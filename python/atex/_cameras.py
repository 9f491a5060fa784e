"""Cameras built in Python (no dataset needed)."""

import math

from ._atex import Asset, Camera


def orbit_camera(asset: Asset, azimuth_deg: float = 30.0, elevation_deg: float = 20.0, width: int = 256,
                 height: int = 192, fov_y_deg: float = 50.0, distance_scale: float = 2.5,
                 t: float = 0.0) -> Camera:
    """A camera looking at the centre of the asset's bounds (metadata bounds_min/max) from a point on
    a sphere of radius distance_scale x the bounds' half-diagonal, OpenCV axes (x right, y down,
    z forward), world +z up, vertical field of view fov_y_deg, at scene time t."""
    meta = asset.metadata
    lo, hi = meta["bounds_min"], meta["bounds_max"]
    center = [(a + b) / 2 for a, b in zip(lo, hi)]
    radius = max(1e-6, math.sqrt(sum(((b - a) / 2) ** 2 for a, b in zip(lo, hi)))) * distance_scale
    az, el = math.radians(azimuth_deg), math.radians(elevation_deg)
    eye = [center[0] + radius * math.cos(el) * math.cos(az),
           center[1] + radius * math.cos(el) * math.sin(az),
           center[2] + radius * math.sin(el)]
    forward = [c - e for c, e in zip(center, eye)]
    n = math.sqrt(sum(f * f for f in forward))
    forward = [f / n for f in forward]
    up = [0.0, 0.0, 1.0]
    right = [forward[1] * up[2] - forward[2] * up[1], forward[2] * up[0] - forward[0] * up[2],
             forward[0] * up[1] - forward[1] * up[0]]
    n = math.sqrt(sum(r * r for r in right)) or 1.0
    right = [r / n for r in right]
    down = [forward[1] * right[2] - forward[2] * right[1], forward[2] * right[0] - forward[0] * right[2],
            forward[0] * right[1] - forward[1] * right[0]]
    rows = [right, down, forward]
    w2c = []
    for r in rows:
        w2c += r + [-sum(a * b for a, b in zip(r, eye))]
    w2c += [0.0, 0.0, 0.0, 1.0]
    focal = 0.5 * height / math.tan(math.radians(fov_y_deg) / 2)
    return Camera(width, height, focal, focal, width / 2, height / 2, w2c, t, "orbit")
