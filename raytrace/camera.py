"""Camera rays: a pinhole camera, pixel (0, 0) top-left, rows going down.

With ``spp = 1`` each ray passes through its pixel's centre. With ``spp = k²`` the pixel is cut
into a k×k grid and each sample is jittered within its cell (stratified sampling); other
counts jitter over the whole pixel. The jitter is a hash of (seed, sample index), so an image
does not depend on how it is split into passes or threads.

A render may cover a window of the frame only (a crop, pbrt's ``--pixelbounds``): its samples
are numbered within the window (``local``), but every ray, and the jitter, is that of the same
sample of the full frame (its ``global`` index ``pixel·spp + k``, :func:`global_samples`), so a
crop's pixels are those of the full render.
"""

from __future__ import annotations

import math

import numpy as np

from .jit import kernel
from .rays import CAMERA, NO_SHAPE, RayBatch
from .scene import Camera

_M1, _M2, _M3 = np.uint64(0x9E3779B97F4A7C15), np.uint64(0xBF58476D1CE4E5B9), np.uint64(
    0x94D049BB133111EB)
_ONE, _TWO = np.uint64(1), np.uint64(2)
_S11, _S27, _S30, _S31 = np.uint64(11), np.uint64(27), np.uint64(30), np.uint64(31)


@kernel
def uniform1(seed, index, stream):
    """A uniform float in [0, 1) from SplitMix64 of (seed, index, stream) (Steele et al. 2014):
    the top 53 bits of the mixed ``(2·index + stream)·M1 + seed·M3``, modulo 2⁶⁴."""
    z = (np.uint64(index) * _TWO + np.uint64(stream)) * _M1 + np.uint64(seed) * _M3
    z = (z ^ (z >> _S30)) * _M2
    z = (z ^ (z >> _S27)) * _M3
    z = z ^ (z >> _S31)
    return float(z >> _S11) * 2.0**-53


@kernel
def offset1(spp, k, seed, sample):
    """Position (sx, sy) in [0, 1)² inside its pixel of global sample ``sample``: the centre for
    spp = 1, jittered in cell (j mod k, j div k) of a k×k grid for spp = k² (j = sample mod
    spp), jittered over the whole pixel otherwise (k = 0)."""
    if spp == 1:
        return 0.5, 0.5
    u1, u2 = uniform1(seed, sample, 0), uniform1(seed, sample, 1)
    if k == 0:
        return u1, u2
    cell = sample % spp
    return (cell % k + u1) / k, (cell // k + u2) / k


@kernel
def _uniform_rows(seed, index, stream, out):
    for i in range(index.shape[0]):
        out[i] = uniform1(seed, index[i], stream)


@kernel
def _offset_rows(spp, k, seed, sample, sx, sy):
    for i in range(sample.shape[0]):
        sx[i], sy[i] = offset1(spp, k, seed, sample[i])


@kernel
def _directions(start, width, height, spp, k, seed, tan_half, right, up, forward, x0, y0, x1,
                out):
    """Unit directions of the samples ``start …`` of the window of columns ``x0 … x1 − 1``
    from row ``y0`` on (the whole frame: 0, 0, ``width``) into ``out`` (n, 3): through
    ``x = (2(col + sx)/W − 1)·tan(fov/2)·W/H``, ``y = (1 − 2(row + sy)/H)·tan(fov/2)`` on the
    image plane one unit along ``forward``, jittered by the sample's global index ``g``. The
    pixel (row, col), the sample's cell within it and ``g`` are counted along, not divided
    out of the sample index for every sample."""
    rx, ry, rz = right[0], right[1], right[2]
    ux, uy, uz = up[0], up[1], up[2]
    fx, fy, fz = forward[0], forward[1], forward[2]
    aspect = width / height
    cols = x1 - x0
    pixel, cell = start // spp, start % spp
    row, col = y0 + pixel // cols, x0 + pixel % cols
    g = (row * width + col) * spp + cell
    for j in range(out.shape[0]):
        if spp == 1:
            sx = sy = 0.5
        else:
            u1, u2 = uniform1(seed, g, 0), uniform1(seed, g, 1)
            if k == 0:
                sx, sy = u1, u2
            else:
                sx, sy = (cell % k + u1) / k, (cell // k + u2) / k
        x = (2.0 * (col + sx) / width - 1.0) * tan_half * aspect
        y = (1.0 - 2.0 * (row + sy) / height) * tan_half
        dx = x * rx + y * ux + fx
        dy = x * ry + y * uy + fy
        dz = x * rz + y * uz + fz
        length = math.sqrt(dx * dx + dy * dy + dz * dz)
        out[j, 0], out[j, 1], out[j, 2] = dx / length, dy / length, dz / length
        cell += 1
        g += 1
        if cell == spp:
            cell = 0
            col += 1
            if col == x1:
                col = x0
                row += 1
                g += (width - cols) * spp


def _grid(spp: int) -> int:
    """k for a k×k stratified grid of ``spp`` samples, 0 when spp is not a square."""
    k = math.isqrt(spp)
    return k if k * k == spp else 0


def hash_uniform(seed: int, index: np.ndarray, stream: int) -> np.ndarray:
    """Uniform floats in [0, 1) from SplitMix64 of (seed, index, stream) (Steele et al. 2014)."""
    index = np.ascontiguousarray(index, dtype=np.int64)
    out = np.empty(index.shape)
    _uniform_rows(seed, index.reshape(-1), stream, out.reshape(-1))
    return out


def sample_offsets(spp: int, seed: int, sample: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions (sx, sy) in [0, 1)² inside the pixel of global sample indices ``sample``."""
    sample = np.ascontiguousarray(sample, dtype=np.int64).reshape(-1)
    sx, sy = np.empty(len(sample)), np.empty(len(sample))
    _offset_rows(spp, _grid(spp), seed, sample, sx, sy)
    return sx, sy


def camera_rays(camera: Camera, width: int, height: int, spp: int, seed: int,
                start: int, stop: int, columns: RayBatch | None = None,
                direction: np.ndarray | None = None,
                window: tuple[int, int, int, int] | None = None) -> RayBatch:
    """Rays of samples ``start..stop-1`` (sample = pixel·spp + k, pixels counted row by row
    in ``window`` = (x0, y0, x1, y1), half-open; the whole frame when None), from the origin:
    the scene is camera-relative.

    ``columns``: a batch of at least ``stop − start`` rows from :func:`camera_columns` whose
    columns other than the direction are reused (views of its first rows); ``direction``: an
    (n, 3) float64 array to write the directions into. Both new when not given.
    """
    n = stop - start
    if direction is None:
        direction = np.empty((n, 3))
    camera_directions(camera, width, height, spp, seed, start, direction, window)
    if columns is None:
        columns = camera_columns(n)
    return RayBatch(origin=columns.origin[:n], direction=direction, sample=columns.sample[:n],
                    weight=columns.weight[:n], depth=0, origin_shape=columns.origin_shape[:n],
                    kind=columns.kind[:n])


def camera_directions(camera: Camera, width: int, height: int, spp: int, seed: int,
                      start: int, out: np.ndarray,
                      window: tuple[int, int, int, int] | None = None) -> None:
    """Unit directions (n, 3) of samples ``start …`` of ``window`` (the whole frame when
    None) into ``out``."""
    tan_half = math.tan(math.radians(camera.fov) / 2.0)
    right, up, forward = (np.ascontiguousarray(v, dtype=np.float64) for v in camera.basis())
    x0, y0, x1, _ = window or (0, 0, width, height)
    _directions(start, width, height, spp, _grid(spp), seed, tan_half, right, up, forward,
                x0, y0, x1, out)


def global_samples(local: np.ndarray, width: int, spp: int,
                   window: tuple[int, int, int, int] | None) -> np.ndarray:
    """Global sample indices ``pixel·spp + k`` of the full ``width``-wide frame, (n,) int64,
    of samples ``local`` (n,) numbered within ``window`` = (x0, y0, x1, y1); the same
    indices when ``window`` is None."""
    local = np.asarray(local, dtype=np.int64)
    if window is None:
        return local
    x0, y0, x1, _ = window
    pixel, cell = np.divmod(local, spp)
    row, col = np.divmod(pixel, x1 - x0)
    return ((row + y0) * width + col + x0) * spp + cell


def camera_columns(n: int) -> RayBatch:
    """The columns every pass's camera rays share, for ``n`` rays: origin 0 (the scene is
    camera-relative), sample 0…n−1 within the pass, weight 1, no start shape, kind CAMERA; the
    direction column is empty. Nothing writes into a batch's columns once it is made (each
    step writes new arrays), so the integrator keeps one of these per thread for all its
    passes instead of filling 65 bytes a ray anew."""
    return RayBatch(origin=np.zeros((n, 3)), direction=np.zeros((0, 3)),
                    sample=np.arange(n, dtype=np.int64), weight=np.ones((n, 3)), depth=0,
                    origin_shape=np.full(n, NO_SHAPE, np.int64),
                    kind=np.full(n, CAMERA, np.int8))
