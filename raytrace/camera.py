"""Camera rays: a pinhole camera, pixel (0, 0) top-left, rows going down.

With ``spp = 1`` each ray passes through its pixel's centre. With ``spp = k²`` the pixel is cut
into a k×k grid and each sample is jittered within its cell (stratified sampling); other
counts jitter over the whole pixel. The jitter is a hash of (seed, sample index), so an image
does not depend on how it is split into passes or threads.
"""

from __future__ import annotations

import math

import numpy as np

from .rays import CAMERA, NO_SHAPE, RayBatch
from .scene import Camera

_M1, _M2, _M3 = np.uint64(0x9E3779B97F4A7C15), np.uint64(0xBF58476D1CE4E5B9), np.uint64(
    0x94D049BB133111EB)


def hash_uniform(seed: int, index: np.ndarray, stream: int) -> np.ndarray:
    """Uniform floats in [0, 1) from SplitMix64 of (seed, index, stream) (Steele et al. 2014)."""
    with np.errstate(over="ignore"):
        z = (index.astype(np.uint64) * np.uint64(2) + np.uint64(stream)) * _M1 + np.uint64(
            seed) * _M3
        z = (z ^ (z >> np.uint64(30))) * _M2
        z = (z ^ (z >> np.uint64(27))) * _M3
        z = z ^ (z >> np.uint64(31))
    return (z >> np.uint64(11)).astype(np.float64) * 2.0**-53


def sample_offsets(spp: int, seed: int, sample: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions (sx, sy) in [0, 1)² inside the pixel of global sample indices ``sample``."""
    if spp == 1:
        half = np.full(len(sample), 0.5)
        return half, half.copy()
    u1 = hash_uniform(seed, sample, 0)
    u2 = hash_uniform(seed, sample, 1)
    k = math.isqrt(spp)
    if k * k != spp:
        return u1, u2
    cell = sample % spp
    return (cell % k + u1) / k, (cell // k + u2) / k


def camera_rays(camera: Camera, width: int, height: int, spp: int, seed: int,
                start: int, stop: int) -> RayBatch:
    """Rays of global samples ``start..stop-1`` (sample = pixel·spp + k), from the origin:
    the scene is camera-relative.
    """
    sample = np.arange(start, stop, dtype=np.int64)
    pixel = sample // spp
    row, col = pixel // width, pixel % width
    sx, sy = sample_offsets(spp, seed, sample)
    tan_half = math.tan(math.radians(camera.fov) / 2.0)
    x = (2.0 * (col + sx) / width - 1.0) * tan_half * (width / height)
    y = (1.0 - 2.0 * (row + sy) / height) * tan_half
    right, up, forward = camera.basis()
    d = x[:, None] * right + y[:, None] * up + forward
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    n = len(sample)
    return RayBatch(origin=np.zeros((n, 3)), direction=d, sample=sample - start,
                    weight=np.ones((n, 3)), depth=0,
                    origin_shape=np.full(n, NO_SHAPE, np.int64),
                    kind=np.full(n, CAMERA, np.int8))
